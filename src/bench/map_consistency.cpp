#include "mrslam/bench/map_consistency.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <unordered_map>

#include "mrslam/bench/cell_key.h"

namespace mrslam::bench {

namespace {

struct Counts {
  uint32_t hits = 0, misses = 0;
};

}  // namespace

MapConsistency mapConsistency(const std::vector<const slam::LaserScan*>& scans, const std::vector<Pose2D>& poses,
                              const Pose2D& laser_in_base, double resolution, double max_range) {
  std::unordered_map<int64_t, Counts> cells;
  auto cell = [&](double v) { return static_cast<int>(std::floor(v / resolution)); };
  for (size_t i = 0; i < scans.size() && i < poses.size(); ++i) {
    const slam::LaserScan& scan = *scans[i];
    const Pose2D laser = poses[i].compose(laser_in_base);
    const int x0 = cell(laser.x), y0 = cell(laser.y);
    for (size_t b = 0; b < scan.ranges.size(); ++b) {
      const float r = scan.ranges[b];
      if (!slam::isReturn(scan, r) || r > max_range) continue;
      const double a = laser.yaw + scan.angle_min + b * scan.angle_increment;
      const int x1 = cell(laser.x + r * std::cos(a)), y1 = cell(laser.y + r * std::sin(a));
      // Bresenham from the laser to the end cell: misses on the way, a hit at the end.
      int x = x0, y = y0;
      const int dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0), sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
      int err = dx + dy;
      while (x != x1 || y != y1) {
        ++cells[cellKey(x, y)].misses;
        const int e2 = 2 * err;
        if (e2 >= dy) err += dy, x += sx;
        if (e2 <= dx) err += dx, y += sy;
      }
      ++cells[cellKey(x1, y1)].hits;
    }
  }
  MapConsistency out;
  size_t conflicted = 0;
  for (const auto& [k, c] : cells) {
    out.hits += c.hits;
    if (c.misses > c.hits) conflicted += c.hits;
  }
  out.conflict = out.hits ? static_cast<double>(conflicted) / out.hits : 0.0;
  return out;
}

}  // namespace mrslam::bench
