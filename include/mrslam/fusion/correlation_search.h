// Our extension for maps with no usable initial guess: for one candidate rotation, the
// translations at which map B's obstacles best overlay map A's, found for all translations at
// once by cross-correlation in the Fourier domain (on a coarse pyramid level). The score is
//   sum(A_walls_blurred * B_walls) - penalty * (sum(A_free * B_walls) + sum(A_walls * B_free)),
// i.e. the similarity index with free-space conflicts, evaluated everywhere in O(N log N).
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "mrslam/fusion/cell_transform.h"

namespace mrslam::fusion {

class CorrelationSearch {
 public:
  CorrelationSearch(const cv::Mat& ternary_a, const cv::Mat& ternary_b, double conflict_penalty);

  // The `count` best translations for rotation `theta`, best first (non-maximum suppression
  // keeps peaks at least `separation` cells apart).
  std::vector<CellTransform> candidates(double theta, int count, int separation) const;

 private:
  cv::Mat ternary_b_;
  cv::Size padded_;
  cv::Mat spectrum_walls_a_, spectrum_free_a_, spectrum_walls_only_a_;
  double penalty_;
};

// B's ternary image rotated by theta into a canvas that holds all of it: canvas pixel
// coordinates are R(theta) u + offset for B's cell coordinates u. Unknown outside B.
cv::Mat rotateTernary(const cv::Mat& ternary, double theta, cv::Point2d& offset);

}  // namespace mrslam::fusion
