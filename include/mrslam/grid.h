// ROS-free occupancy grid and 2D pose types shared by the whole core.
//
// The grid follows nav_msgs/OccupancyGrid exactly (so the nodelets convert without
// reinterpretation): data is row-major, row 0 is the bottom row (lowest y), values are
// -1 (unknown) or 0..100 (occupancy probability in percent). `origin` is the pose of the
// lower-left corner of cell (0, 0) in the map frame, as in map_server yaml files.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace mrslam {

struct Pose2D {
  double x = 0.0;
  double y = 0.0;
  double yaw = 0.0;  // radians

  // this ∘ other: apply `other` first, then `this`.
  Pose2D compose(const Pose2D& other) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return {x + c * other.x - s * other.y, y + s * other.x + c * other.y,
            normalizeAngle(yaw + other.yaw)};
  }
  Pose2D inverse() const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return {-(c * x + s * y), s * x - c * y, normalizeAngle(-yaw)};
  }
  void apply(double px, double py, double& ox, double& oy) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    const double rx = x + c * px - s * py, ry = y + s * px + c * py;  // safe if &ox == &px
    ox = rx;
    oy = ry;
  }
  static double normalizeAngle(double a) { return std::remainder(a, 2.0 * M_PI); }
};

struct OccupancyGrid {
  static constexpr int8_t kUnknown = -1;

  int width = 0;
  int height = 0;
  double resolution = 0.0;  // metres per cell
  Pose2D origin;            // pose of the lower-left corner of cell (0, 0)
  std::vector<int8_t> data;

  int8_t at(int col, int row) const { return data[static_cast<size_t>(row) * width + col]; }
  int8_t& at(int col, int row) { return data[static_cast<size_t>(row) * width + col]; }
  bool empty() const { return width <= 0 || height <= 0; }
};

// Origins further than this from their frame are refused (m): no map is that large, and cell
// indices computed from such offsets would overflow.
constexpr double kMaxOriginMetres = 1e6;
// Resolutions outside this range (m per cell) are refused: no occupancy grid is finer than a
// tenth of a millimetre or coarser than a kilometre, and distances in cells computed from such
// resolutions would overflow cell indices.
constexpr double kMinResolution = 1e-4, kMaxResolution = 1e3;

// Checks the invariants every consumer relies on; returns an empty string when the grid
// is well formed, otherwise a one-line description of what is wrong. `max_cells` guards
// against absurd sizes sent by a faulty peer.
std::string validateGrid(const OccupancyGrid& grid, int64_t max_cells = 400LL * 1000 * 1000);

}  // namespace mrslam
