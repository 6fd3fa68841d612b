// Our extension to stage 8: sub-cell polish of the final pose.
//
// The similarity index counts a wall as agreeing anywhere within one cell of A's wall, so it
// is flat over a small plateau of poses, and its arg-max can sit a fraction of a degree off
// (a cell or two at 30 m). The polish minimises the chamfer distance instead: the distance
// from each of B's wall cells to A's nearest wall, read with sub-cell (bilinear) precision
// from A's distance transform and truncated so that walls only one map has do not pull.
// Gauss-Newton over (theta, tx, ty) converges in a few iterations.
#pragma once

#include <array>
#include <opencv2/core.hpp>
#include <vector>

#include "mrslam/fusion/cell_transform.h"

namespace mrslam::fusion {

// Distance (cells) from each cell to the nearest obstacle cell of a ternary image, exact below
// `reach` and `ceil(reach)` everywhere farther (a reach of at most 10 cells: the polish never
// reads farther, see chamfer_truncation in config/fusion.yaml).
cv::Mat truncatedWallDistance(const cv::Mat& ternary, double reach);

class ChamferPolish {
 public:
  // `truncation` (cells): B's wall cells farther than this from A's walls are ignored.
  ChamferPolish(const cv::Mat& ternary_a, const cv::Mat& ternary_b, double truncation = 2.0,
                int max_points = 4000);

  CellTransform polish(const CellTransform& start, int iterations = 20) const;

  // Mean truncated distance (cells) of B's walls that reach A's walls at `transform`.
  double meanDistance(const CellTransform& transform) const;

 private:
  // Bilinear read of A's wall distance at continuous cell coordinates; false off the map.
  bool distanceAt(double x, double y, float& out) const;

  // A's distance transform: per cell the squared offset to its nearest wall, as a byte code,
  // and the distance (cells) each code stands for.
  cv::Mat squared_offsets_;
  std::array<float, 256> distance_of_code_;
  std::vector<cv::Point2f> walls_b_;     // relative to their centroid
  cv::Point2d centre_b_;
  double truncation_;
};

}  // namespace mrslam::fusion
