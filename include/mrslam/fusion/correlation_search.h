// Our extension for maps with no usable initial guess: for one candidate rotation, the
// translations with the best similarity score, found for all translations at once by
// cross-correlation in the Fourier domain (on a coarse pyramid level). The score is exactly
// SimilarityIndex's agr - w * dis (same cell classes and one-cell wall tolerance), because
// each of its four counts is a correlation of a mask of A with a mask of B:
//   score = corr(A_wall_or_near - w A_free, B_walls) + corr(A_free_or_near - w A_walls, B_free)
// so the candidates are ranked as the later stages will rank them.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "mrslam/fusion/cell_transform.h"

namespace mrslam::fusion {

class CorrelationSearch {
 public:
  CorrelationSearch(const cv::Mat& ternary_a, const cv::Mat& ternary_b, double disagreement_weight);

  // The `count` best translations for rotation `theta` and the `count` best for theta + pi,
  // each best first (non-maximum suppression keeps peaks `separation` cells apart). B turned
  // by another pi is B's canvas point-reflected, whose correlation is the convolution with
  // the same spectrum: both rotations cost one set of Fourier transforms.
  std::vector<CellTransform> candidates(double theta, int count, int separation) const;

 private:
  cv::Mat ternary_b_;
  cv::Size padded_;
  cv::Mat spectrum_for_b_walls_, spectrum_for_b_free_;  // of A's weighted masks
};

// B's ternary image rotated by theta into a canvas that holds all of it: canvas pixel
// coordinates are R(theta) u + offset for B's cell coordinates u. Unknown outside B.
cv::Mat rotateTernary(const cv::Mat& ternary, double theta, cv::Point2d& offset);

}  // namespace mrslam::fusion
