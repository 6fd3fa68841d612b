// The paper's hypothesis generator, stages 1-6 chained: Canny edges, edge smoothing, random
// segments verified by their histograms, segments of A matched against segments of B by
// cross-correlation, and an approximate pose from every matched pair.
#pragma once

#include <random>
#include <vector>

#include "mrslam/fusion/cell_transform.h"
#include "mrslam/fusion/segment.h"
#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {

struct SegmentMatchingParams {
  CannyParams canny;
  int smoothing_distance = 2;     // d_t, cells
  SegmentParams segment;
  int trials = 60;                // random segments drawn per map
  double min_correlation = 0.9;   // matched when all four correlations reach this
  int max_pairs = 6;              // best matched pairs turned into pose hypotheses
};

struct SegmentFeatures {
  std::vector<Segment> segments;              // verified segments only
  std::vector<SegmentSignature> signatures;
};

// Draws `trials` random segments from the smoothed edges of `ternary` and keeps the verified.
SegmentFeatures extractSegments(const cv::Mat& ternary, const SegmentMatchingParams& params,
                                std::mt19937& rng);

// Approximate poses (two per matched pair, see approximatePose) of the best-correlated pairs.
std::vector<CellTransform> segmentHypotheses(const SegmentFeatures& a, const SegmentFeatures& b,
                                             const SegmentMatchingParams& params);

}  // namespace mrslam::fusion
