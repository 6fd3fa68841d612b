#include "mrslam/fusion/grid_merge.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mrslam::fusion {

OccupancyGrid mergeGrids(const OccupancyGrid& reference, const std::vector<PlacedGrid>& others) {
  std::vector<PlacedGrid> all{{&reference, Pose2D{}}};
  all.insert(all.end(), others.begin(), others.end());

  // Bounding box of every grid's corners in the reference grid frame (metres).
  const Pose2D to_ref_grid = reference.origin.inverse();
  double min_x = std::numeric_limits<double>::max(), min_y = min_x, max_x = -min_x, max_y = -min_x;
  for (const PlacedGrid& p : all) {
    const Pose2D grid_in_ref = to_ref_grid.compose(p.pose).compose(p.grid->origin);
    const double w = p.grid->width * p.grid->resolution, h = p.grid->height * p.grid->resolution;
    for (const auto& [cx, cy] : {std::pair{0.0, 0.0}, {w, 0.0}, {0.0, h}, {w, h}}) {
      double x, y;
      grid_in_ref.apply(cx, cy, x, y);
      min_x = std::min(min_x, x), max_x = std::max(max_x, x);
      min_y = std::min(min_y, y), max_y = std::max(max_y, y);
    }
  }
  const double res = reference.resolution;
  // Keep the reference's cell lattice: shift the bounds to whole cells.
  const int c0 = static_cast<int>(std::floor(min_x / res)), r0 = static_cast<int>(std::floor(min_y / res));
  OccupancyGrid out;
  out.resolution = res;
  out.width = static_cast<int>(std::ceil(max_x / res)) - c0;
  out.height = static_cast<int>(std::ceil(max_y / res)) - r0;
  out.origin = reference.origin.compose(Pose2D{c0 * res, r0 * res, 0.0});

  std::vector<float> log_odds(static_cast<size_t>(out.width) * out.height, 0.0f);
  std::vector<uint8_t> known(log_odds.size(), 0);
  float lut[101];
  for (int v = 0; v <= 100; ++v) {
    const double p = std::clamp(v / 100.0, 0.02, 0.98);
    lut[v] = static_cast<float>(std::log(p / (1.0 - p)));
  }
  for (const PlacedGrid& p : all) {
    const OccupancyGrid& g = *p.grid;
    // Output cell centre (grid frame of out) -> this grid's cell coordinates: an affine map.
    const Pose2D out_to_g = g.origin.inverse().compose(p.pose.inverse()).compose(out.origin);
    const double c = std::cos(out_to_g.yaw) / g.resolution, s = std::sin(out_to_g.yaw) / g.resolution;
    const double tx = out_to_g.x / g.resolution, ty = out_to_g.y / g.resolution;
    // Only the output cells under this grid's bounding box can read from it.
    int col0 = out.width, col1 = -1, row0 = out.height, row1 = -1;
    const double w = g.width * g.resolution, h = g.height * g.resolution;
    for (const auto& [gx, gy] : {std::pair{0.0, 0.0}, {w, 0.0}, {0.0, h}, {w, h}}) {
      double x, y;  // the corner in out's grid frame (metres)
      out.origin.inverse().compose(p.pose).compose(g.origin).apply(gx, gy, x, y);
      col0 = std::min(col0, static_cast<int>(std::floor(x / res)) - 1), col1 = std::max(col1, static_cast<int>(std::ceil(x / res)) + 1);
      row0 = std::min(row0, static_cast<int>(std::floor(y / res)) - 1), row1 = std::max(row1, static_cast<int>(std::ceil(y / res)) + 1);
    }
    col0 = std::max(col0, 0), row0 = std::max(row0, 0);
    col1 = std::min(col1, out.width - 1), row1 = std::min(row1, out.height - 1);
    for (int r = row0; r <= row1; ++r) {
      const double y = (r + 0.5) * res;
      for (int col = col0; col <= col1; ++col) {
        const double x = (col + 0.5) * res;
        const double gx = c * x - s * y + tx, gy = s * x + c * y + ty;
        if (gx < 0 || gy < 0 || gx >= g.width || gy >= g.height) continue;
        const int v = g.at(static_cast<int>(gx), static_cast<int>(gy));
        if (v < 0) continue;
        const size_t i = static_cast<size_t>(r) * out.width + col;
        log_odds[i] += lut[v];
        known[i] = 1;
      }
    }
  }
  out.data.resize(log_odds.size());
  for (size_t i = 0; i < log_odds.size(); ++i)
    out.data[i] = known[i] ? static_cast<int8_t>(std::lround(100.0 / (1.0 + std::exp(-log_odds[i]))))
                           : OccupancyGrid::kUnknown;
  return out;
}

}  // namespace mrslam::fusion
