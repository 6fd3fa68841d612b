#include "mrslam/bench/wall_directions.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "mrslam/bench/cell_key.h"

namespace mrslam::bench {

namespace {

using Cells = std::vector<std::pair<double, double>>;  // wall cells' positions, in cells

constexpr double kDeg = M_PI / 180.0;

// Sum of squared counts of the cells projected on `angle` and on its perpendicular, in bins one
// cell wide: largest where the walls line up with the two directions. `reach` bounds |x| + |y|.
double pileUp(const Cells& cells, double angle, double reach) {
  const double c = std::cos(angle), s = std::sin(angle);
  std::vector<uint32_t> bins(2 * static_cast<size_t>(std::ceil(reach)) + 2);
  double total = 0;
  for (const bool across : {false, true}) {
    std::fill(bins.begin(), bins.end(), 0u);
    for (const auto& [x, y] : cells) ++bins[static_cast<size_t>(std::floor((across ? c * x + s * y : c * y - s * x) + reach))];
    for (const uint32_t count : bins) total += static_cast<double>(count) * count;
  }
  return total;
}

// The direction in [from, to) (radians, stepped by `step`) at which the cells pile up most.
double direction(Cells cells, double from, double to, double step) {
  double mean_x = 0, mean_y = 0, reach = 0;
  for (const auto& [x, y] : cells) mean_x += x / cells.size(), mean_y += y / cells.size();
  for (auto& [x, y] : cells) x -= mean_x, y -= mean_y, reach = std::max(reach, std::abs(x) + std::abs(y));
  double best = from, best_pile = -1;
  const int steps = static_cast<int>(std::lround((to - from) / step));
  for (int i = 0; i < steps; ++i) {
    const double a = from + i * step, pile = pileUp(cells, a, reach);
    if (pile > best_pile) best_pile = pile, best = a;
  }
  return best;
}

// The cells where at least min_hits returns end, each at the mean of its returns (in cells):
// cell centres lie on a lattice, which piles up along directions of small integer slope (2/3,
// 1/2, ...) wherever walls are smeared, and would pull every region's direction onto the axis.
Cells wallCells(const std::vector<const slam::LaserScan*>& scans, const std::vector<Pose2D>& poses,
                const Pose2D& laser_in_base, const WallDirectionsParams& p) {
  struct Hits {
    double x = 0, y = 0;
    uint32_t count = 0;
  };
  std::unordered_map<int64_t, Hits> hits;
  for (size_t i = 0; i < scans.size() && i < poses.size(); ++i) {
    const Pose2D laser = poses[i].compose(laser_in_base);
    for (const auto& [px, py] : slam::scanPoints(*scans[i], laser)) {
      if (std::hypot(px - laser.x, py - laser.y) > p.max_range) continue;
      const double x = px / p.resolution, y = py / p.resolution;
      Hits& cell = hits[cellKey(static_cast<int64_t>(std::floor(x)), static_cast<int64_t>(std::floor(y)))];
      cell.x += x, cell.y += y, ++cell.count;
    }
  }
  Cells cells;
  for (const auto& [k, cell] : hits)
    if (cell.count >= static_cast<uint32_t>(p.min_hits)) cells.emplace_back(cell.x / cell.count, cell.y / cell.count);
  std::sort(cells.begin(), cells.end());  // the hash map's order would make ties depend on it
  return cells;
}

// The values at fractions 0, 1/k, ..., 1 of `v` sorted (v not empty): cuts into k bands holding
// equal shares of the values.
std::vector<double> quantiles(std::vector<double> v, int k) {
  std::sort(v.begin(), v.end());
  std::vector<double> q;
  for (int i = 0; i <= k; ++i) q.push_back(v[std::min(v.size() - 1, v.size() * static_cast<size_t>(i) / static_cast<size_t>(k))]);
  q.back() = v.back() + 1;  // the last region holds the largest value
  return q;
}

}  // namespace

WallDirections wallDirections(const std::vector<const slam::LaserScan*>& scans, const std::vector<Pose2D>& poses,
                              const Pose2D& laser_in_base, const WallDirectionsParams& params) {
  WallDirections out;
  const Cells cells = wallCells(scans, poses, laser_in_base, params);
  const int k = std::max(1, params.regions_per_side);
  if (cells.empty() || cells.size() < params.min_region_cells) return out;
  // The whole map's axis to a tenth of a degree; each region's within 3 degrees of it.
  const double axis = direction(cells, -45 * kDeg, 45 * kDeg, 0.1 * kDeg);
  out.axis_deg = axis / kDeg;
  const double c = std::cos(axis), s = std::sin(axis);
  std::vector<double> along, across;
  for (const auto& [x, y] : cells) along.push_back(c * x + s * y), across.push_back(-s * x + c * y);
  const auto along_cut = quantiles(along, k), across_cut = quantiles(across, k);
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j) {
      Cells region;
      for (size_t n = 0; n < cells.size(); ++n)
        if (along[n] >= along_cut[i] && along[n] < along_cut[i + 1] && across[n] >= across_cut[j] &&
            across[n] < across_cut[j + 1])
          region.push_back(cells[n]);
      if (region.size() < params.min_region_cells) continue;
      out.region_deg.push_back((direction(region, axis - 3 * kDeg, axis + 3 * kDeg, 0.05 * kDeg) - axis) / kDeg);
    }
  if (out.region_deg.empty()) return out;
  const auto [lo, hi] = std::minmax_element(out.region_deg.begin(), out.region_deg.end());
  out.spread_deg = *hi - *lo;
  double mean = 0, square = 0;
  for (double d : out.region_deg) mean += d / out.region_deg.size();
  for (double d : out.region_deg) square += (d - mean) * (d - mean) / out.region_deg.size();
  out.std_deg = std::sqrt(square);
  return out;
}

}  // namespace mrslam::bench
