#include "mrslam/grid.h"

#include <sstream>

namespace mrslam {

std::string validateGrid(const OccupancyGrid& grid, int64_t max_cells) {
  std::ostringstream why;
  if (!(grid.resolution > 0.0) || !std::isfinite(grid.resolution)) {
    why << "resolution must be a positive finite number (got " << grid.resolution << ")";
  } else if (grid.resolution < kMinResolution || grid.resolution > kMaxResolution) {
    why << "resolution " << grid.resolution << " m is outside " << kMinResolution << ".." << kMaxResolution << " m";
  } else if (grid.width <= 0 || grid.height <= 0) {
    why << "grid is empty (" << grid.width << " x " << grid.height << " cells)";
  } else if (static_cast<int64_t>(grid.width) * grid.height > max_cells) {
    why << "grid of " << grid.width << " x " << grid.height << " cells exceeds the limit of "
        << max_cells << " cells";
  } else if (grid.data.size() != static_cast<size_t>(grid.width) * grid.height) {
    why << "data has " << grid.data.size() << " cells but width x height is "
        << static_cast<int64_t>(grid.width) * grid.height;
  } else if (!std::isfinite(grid.origin.x) || !std::isfinite(grid.origin.y) ||
             !std::isfinite(grid.origin.yaw)) {
    why << "origin is not finite";
  } else if (std::abs(grid.origin.x) > kMaxOriginMetres || std::abs(grid.origin.y) > kMaxOriginMetres) {
    // Map extents are computed from origins: a planet-sized offset would overflow cell indices.
    why << "origin (" << grid.origin.x << ", " << grid.origin.y << ") lies more than " << kMaxOriginMetres
        << " m from the frame";
  } else {
    for (int8_t v : grid.data) {
      if (v < -1 || v > 100) {
        why << "cell value " << int(v) << " outside -1..100";
        break;
      }
    }
  }
  return why.str();
}

}  // namespace mrslam
