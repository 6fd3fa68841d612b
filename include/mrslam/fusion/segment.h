// Stages 3-5: random segment, segment verification and cross-correlation.
//
// Notation follows the paper: a segment P is n connected obstacle points P(0..n-1) along a
// smoothed edge; D holds d_i = |P(i) - P(0)|, Delta the differential angles
// delta_i = angle(P(i) - P(0)) - angle(P(i-1) - P(0)), the arc vector Omega holds
// omega_i = d_{i+1} * sum_{j<=i} delta_j; hist_d and hist_a are histograms of D and Omega.
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace mrslam::fusion {

using Segment = std::vector<cv::Point2f>;

// Stage 3. Walks `n` connected (8-neighbourhood) points along the one-cell-wide curves of
// `skeleton`, starting at a random curve point and continuing straight where it can.
// Returns nothing when the curve ends before n points.
std::optional<Segment> randomSegment(const cv::Mat& skeleton,
                                     const std::vector<cv::Point>& curve_points, int n,
                                     std::mt19937& rng);

struct SegmentParams {
  int points = 40;          // n
  int distance_bins = 8;    // nd
  int arc_bins = 8;         // na
  double h_d = 3.0;         // condition 2: max(hist_d) - min(hist_d) >= h_d
  double omega_c = 60.0;    // condition 3: max |omega_i| < omega_c (cells x rad)
};

struct SegmentSignature {
  std::vector<double> D, delta, omega;
  std::vector<double> hist_d, hist_a;
};

SegmentSignature computeSignature(const Segment& segment, const SegmentParams& params);

// Stage 4: the paper's three conditions. On rejection `why` (if given) names the condition.
bool verifySegment(const SegmentSignature& signature, const SegmentParams& params,
                   std::string* why = nullptr);

// Stage 5: similarity of two verified segments: the normalized (zero-lag) cross-correlation
// of hist_d, hist_a, and of the vectors D and Omega. The weakest of the four is returned, in
// [-1, 1]; matching segments score close to 1 on all of them.
double segmentCorrelation(const SegmentSignature& a, const SegmentSignature& b);

// Pearson correlation of two equally long sequences (0 when either is constant).
double normalizedCorrelation(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace mrslam::fusion
