// A grid of how likely a laser return is at each cell, given reference points (the returns of
// earlier scans): exp(-d^2 / 2 sigma^2) for d the distance to the nearest reference point,
// zero beyond 3 sigma, stored as 0..255 (a byte a cell keeps large search grids small). Scan
// matchers score a pose by the mean value under the scan's points, as a share of 255.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "mrslam/grid.h"

namespace mrslam::slam {

using Points2 = std::vector<std::pair<float, float>>;

class LikelihoodGrid {
 public:
  LikelihoodGrid() = default;
  // Covers the points plus `margin` metres on every side. `sigma` in metres.
  LikelihoodGrid(const Points2& reference, double resolution, double sigma, double margin);
  // The same grid for new points, in the cells' own buffer: a grid rebuilt at nearly every scan
  // (the tracker's seed) neither allocates nor pages in megabytes each time.
  void rebuild(const Points2& reference, double resolution, double sigma, double margin);

  double resolution() const { return resolution_; }
  double originX() const { return origin_x_; }  // lower-left corner of cell (0, 0)
  double originY() const { return origin_y_; }
  int width() const { return width_; }
  int height() const { return height_; }
  bool empty() const { return values_.empty(); }
  // 0..255, 0 outside the grid.
  uint8_t at(int cx, int cy) const {
    return (cx < 0 || cy < 0 || cx >= width_ || cy >= height_) ? 0 : values_[static_cast<size_t>(cy) * width_ + cx];
  }
  const std::vector<uint8_t>& values() const { return values_; }
  // Mean value under `points` (already in the grid's frame, nearest cell), 0..1.
  double score(const Points2& points) const;

 private:
  double resolution_ = 0.05, origin_x_ = 0, origin_y_ = 0;
  int width_ = 0, height_ = 0;
  std::vector<uint8_t> values_;
};

// Returns closer than `spacing` to the last one kept are dropped (scan order): dense scans
// give many more points than matching needs.
Points2 thinPoints(const Points2& points, double spacing);

// `points` moved by `pose` (applied as a rigid transform).
Points2 transformPoints(const Points2& points, const Pose2D& pose);

}  // namespace mrslam::slam
