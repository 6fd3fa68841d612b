// A rigid transform between two grids in cell units: a cell coordinate u of map B (column,
// row; continuous, row 0 = lowest y) lands at R(theta) * u + t in map A's cell coordinates.
#pragma once

#include <cmath>
#include <opencv2/core.hpp>

namespace mrslam::fusion {

struct CellTransform {
  double theta = 0.0;  // radians
  cv::Point2d t;

  cv::Point2d apply(const cv::Point2d& u) const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {c * u.x - s * u.y + t.x, s * u.x + c * u.y + t.y};
  }
  // The same transform between grids `factor` times coarser (factor > 1) or finer (< 1).
  CellTransform scaled(double factor) const { return {theta, t / factor}; }
};

}  // namespace mrslam::fusion
