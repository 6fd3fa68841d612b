#include "mrslam/bench/pair_maker.h"
#include "mrslam/slam/robot_log.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mrslam::bench {
std::vector<LaserScan2D> readCarmenScans(const std::string& path, int* skipped_lines) {
  // One CARMEN reader for the whole project: the front end's (robot_log.h).
  const slam::RobotLog log = slam::readCarmenLog(path);
  std::vector<LaserScan2D> scans;
  scans.reserve(log.records.size());
  for (const slam::LogRecord& r : log.records)
    scans.push_back({r.scan.stamp, r.reference, r.scan.angle_min, r.scan.angle_increment, r.scan.ranges});
  if (skipped_lines) *skipped_lines = static_cast<int>(log.warnings.size());
  return scans;
}

OccupancyGrid raycastMap(const std::vector<LaserScan2D>& scans, size_t first, size_t last,
                         const Pose2D& frame_in_world, const RaycastParams& params, std::mt19937& rng) {
  const Pose2D world_to_frame = frame_in_world.inverse();
  std::normal_distribution<double> unit(0.0, 1.0);
  Pose2D drift;
  std::vector<Pose2D> poses;
  double min_x = std::numeric_limits<double>::max(), min_y = min_x, max_x = -min_x, max_y = -min_x;
  for (size_t k = first; k < last; ++k) {
    if (k > first) {
      const double metres = std::hypot(scans[k].pose.x - scans[k - 1].pose.x, scans[k].pose.y - scans[k - 1].pose.y);
      const double sxy = params.drift_sigma_xy * std::sqrt(metres), syaw = params.drift_sigma_yaw * std::sqrt(metres);
      drift = drift.compose(Pose2D{sxy * unit(rng), sxy * unit(rng), syaw * unit(rng)});
    }
    const Pose2D p = world_to_frame.compose(scans[k].pose.compose(drift));
    poses.push_back(p);
    const double reach = params.max_range;
    min_x = std::min(min_x, p.x - reach), max_x = std::max(max_x, p.x + reach);
    min_y = std::min(min_y, p.y - reach), max_y = std::max(max_y, p.y + reach);
  }
  const double res = params.resolution;
  OccupancyGrid grid;
  grid.resolution = res;
  grid.origin = {std::floor(min_x / res) * res, std::floor(min_y / res) * res, 0.0};
  grid.width = static_cast<int>(std::ceil((max_x - grid.origin.x) / res)) + 1;
  grid.height = static_cast<int>(std::ceil((max_y - grid.origin.y) / res)) + 1;
  std::vector<uint16_t> hits(static_cast<size_t>(grid.width) * grid.height, 0), visits(hits.size(), 0);
  auto bump = [](uint16_t& v) { if (v < 65535) ++v; };
  for (size_t k = 0; k < poses.size(); ++k) {
    const LaserScan2D& scan = scans[first + k];
    const Pose2D& p = poses[k];
    const int x0 = static_cast<int>((p.x - grid.origin.x) / res), y0 = static_cast<int>((p.y - grid.origin.y) / res);
    for (size_t i = 0; i < scan.ranges.size(); ++i) {
      const double r = scan.ranges[i];
      if (!(r > 0.05) || r >= params.max_range) continue;
      const double a = p.yaw + scan.angle_min + i * scan.angle_increment;
      const int x1 = static_cast<int>((p.x + r * std::cos(a) - grid.origin.x) / res);
      const int y1 = static_cast<int>((p.y + r * std::sin(a) - grid.origin.y) / res);
      // Bresenham from the sensor to the hit: free passes, then the hit.
      int x = x0, y = y0;
      const int dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0), sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
      int err = dx + dy;
      while (!(x == x1 && y == y1)) {
        bump(visits[static_cast<size_t>(y) * grid.width + x]);
        const int e2 = 2 * err;
        if (e2 >= dy) err += dy, x += sx;
        if (e2 <= dx) err += dx, y += sy;
      }
      const size_t hit = static_cast<size_t>(y1) * grid.width + x1;
      bump(visits[hit]);
      bump(hits[hit]);
    }
  }
  grid.data.resize(hits.size());
  for (size_t i = 0; i < hits.size(); ++i)
    grid.data[i] = visits[i] == 0 ? OccupancyGrid::kUnknown
                                  : (hits[i] >= params.occupied_ratio * visits[i] ? 100 : 0);
  return trimUnknown(grid);
}

OccupancyGrid reframeGrid(const OccupancyGrid& grid, const Pose2D& frame) {
  // Corners of grid in the new frame.
  const Pose2D grid_in_new = frame.inverse().compose(grid.origin);
  const double w = grid.width * grid.resolution, h = grid.height * grid.resolution;
  double min_x = std::numeric_limits<double>::max(), min_y = min_x, max_x = -min_x, max_y = -min_x;
  for (const auto& [cx, cy] : {std::pair{0.0, 0.0}, {w, 0.0}, {0.0, h}, {w, h}}) {
    double x, y;
    grid_in_new.apply(cx, cy, x, y);
    min_x = std::min(min_x, x), max_x = std::max(max_x, x);
    min_y = std::min(min_y, y), max_y = std::max(max_y, y);
  }
  const double res = grid.resolution;
  OccupancyGrid out;
  out.resolution = res;
  out.origin = {min_x, min_y, 0.0};
  out.width = static_cast<int>(std::ceil((max_x - min_x) / res));
  out.height = static_cast<int>(std::ceil((max_y - min_y) / res));
  out.data.assign(static_cast<size_t>(out.width) * out.height, OccupancyGrid::kUnknown);
  const Pose2D out_to_grid = grid_in_new.inverse().compose(out.origin);
  for (int r = 0; r < out.height; ++r)
    for (int c = 0; c < out.width; ++c) {
      double gx, gy;
      out_to_grid.apply((c + 0.5) * res, (r + 0.5) * res, gx, gy);
      const int ci = static_cast<int>(std::floor(gx / res)), ri = static_cast<int>(std::floor(gy / res));
      if (ci >= 0 && ri >= 0 && ci < grid.width && ri < grid.height) out.at(c, r) = grid.at(ci, ri);
    }
  return trimUnknown(out);
}

OccupancyGrid cropGrid(const OccupancyGrid& grid, int col0, int row0, int cols, int rows) {
  col0 = std::clamp(col0, 0, grid.width - 1), row0 = std::clamp(row0, 0, grid.height - 1);
  cols = std::clamp(cols, 1, grid.width - col0), rows = std::clamp(rows, 1, grid.height - row0);
  OccupancyGrid out;
  out.width = cols, out.height = rows, out.resolution = grid.resolution;
  out.origin = grid.origin.compose(Pose2D{col0 * grid.resolution, row0 * grid.resolution, 0.0});
  out.data.resize(static_cast<size_t>(cols) * rows);
  for (int r = 0; r < rows; ++r)
    std::copy_n(&grid.data[static_cast<size_t>(row0 + r) * grid.width + col0], cols, &out.data[static_cast<size_t>(r) * cols]);
  return out;
}

double knownOverlap(const OccupancyGrid& a, const OccupancyGrid& b, const Pose2D& b_in_a) {
  const Pose2D to_b_grid = b.origin.inverse().compose(b_in_a.inverse()).compose(a.origin);
  size_t known_a = 0, known_b = 0, both = 0;
  for (int8_t v : b.data) known_b += v >= 0;
  for (int r = 0; r < a.height; ++r)
    for (int c = 0; c < a.width; ++c) {
      if (a.at(c, r) < 0) continue;
      ++known_a;
      double x, y;
      to_b_grid.apply((c + 0.5) * a.resolution, (r + 0.5) * a.resolution, x, y);
      const int bc = static_cast<int>(std::floor(x / b.resolution)), br = static_cast<int>(std::floor(y / b.resolution));
      if (bc >= 0 && br >= 0 && bc < b.width && br < b.height && b.at(bc, br) >= 0) ++both;
    }
  // `both` counts A's cells; rescale to B's cell area if resolutions differ.
  const double smaller = std::min(known_a * a.resolution * a.resolution, known_b * b.resolution * b.resolution);
  return smaller > 0 ? both * a.resolution * a.resolution / smaller : 0.0;
}

OccupancyGrid trimUnknown(const OccupancyGrid& grid) {
  int c0 = grid.width, c1 = -1, r0 = grid.height, r1 = -1;
  for (int r = 0; r < grid.height; ++r)
    for (int c = 0; c < grid.width; ++c)
      if (grid.at(c, r) >= 0) c0 = std::min(c0, c), c1 = std::max(c1, c), r0 = std::min(r0, r), r1 = std::max(r1, r);
  if (c1 < 0) return grid;
  return cropGrid(grid, c0, r0, c1 - c0 + 1, r1 - r0 + 1);
}

}  // namespace mrslam::bench
