#include "mrslam/fusion/segment_matching.h"

#include <algorithm>
#include <opencv2/core.hpp>

#include "mrslam/fusion/approximate_pose.h"
#include "mrslam/fusion/edge_smoothing.h"

namespace mrslam::fusion {

SegmentFeatures extractSegments(const cv::Mat& ternary, const SegmentMatchingParams& params,
                                std::mt19937& rng) {
  const cv::Mat curves = smoothEdges(cannyEdges(ternary, params.canny), params.smoothing_distance);
  std::vector<cv::Point> curve_points;
  cv::findNonZero(curves, curve_points);
  SegmentFeatures features;
  for (int i = 0; i < params.trials; ++i) {
    auto segment = randomSegment(curves, curve_points, params.segment.points, rng);
    if (!segment) continue;
    SegmentSignature signature = computeSignature(*segment, params.segment);
    if (!verifySegment(signature, params.segment)) continue;
    features.segments.push_back(std::move(*segment));
    features.signatures.push_back(std::move(signature));
  }
  return features;
}

std::vector<CellTransform> segmentHypotheses(const SegmentFeatures& a, const SegmentFeatures& b,
                                             const SegmentMatchingParams& params) {
  std::vector<std::tuple<double, size_t, size_t>> pairs;
  for (size_t i = 0; i < a.signatures.size(); ++i)
    for (size_t j = 0; j < b.signatures.size(); ++j) {
      const double corr = segmentCorrelation(a.signatures[i], b.signatures[j]);
      if (corr >= params.min_correlation) pairs.emplace_back(corr, i, j);
    }
  std::sort(pairs.rbegin(), pairs.rend());
  std::vector<CellTransform> out;
  for (size_t k = 0; k < pairs.size() && static_cast<int>(k) < params.max_pairs; ++k) {
    const auto [corr, i, j] = pairs[k];
    for (const CellTransform& t : approximatePose(a.segments[i], b.segments[j])) out.push_back(t);
  }
  return out;
}

}  // namespace mrslam::fusion
