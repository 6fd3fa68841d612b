#include "mrslam/slam/likelihood_grid.h"

#include <algorithm>
#include <cmath>

namespace mrslam::slam {

LikelihoodGrid::LikelihoodGrid(const Points2& reference, double resolution, double sigma, double margin) {
  rebuild(reference, resolution, sigma, margin);
}

void LikelihoodGrid::rebuild(const Points2& reference, double resolution, double sigma, double margin) {
  resolution_ = resolution;
  origin_x_ = origin_y_ = 0;
  width_ = height_ = 0;
  values_.clear();
  if (reference.empty() || !(resolution > 0) || !(sigma > 0)) return;
  const int reach = static_cast<int>(std::ceil(3.0 * sigma / resolution));
  margin = std::max(margin, (reach + 1) * resolution);  // the kernel must fit around every point
  float min_x = reference[0].first, max_x = min_x, min_y = reference[0].second, max_y = min_y;
  for (const auto& [x, y] : reference) {
    min_x = std::min(min_x, x), max_x = std::max(max_x, x);
    min_y = std::min(min_y, y), max_y = std::max(max_y, y);
  }
  origin_x_ = min_x - margin;
  origin_y_ = min_y - margin;
  width_ = static_cast<int>(std::ceil((max_x + margin - origin_x_) / resolution)) + 1;
  height_ = static_cast<int>(std::ceil((max_y + margin - origin_y_) / resolution)) + 1;
  values_.assign(static_cast<size_t>(width_) * height_, 0);
  // One kernel stamped (max) at every reference point's cell.
  std::vector<uint8_t> kernel;
  for (int dy = -reach; dy <= reach; ++dy)
    for (int dx = -reach; dx <= reach; ++dx) {
      const double d2 = (dx * dx + dy * dy) * resolution * resolution;
      kernel.push_back(d2 > 9 * sigma * sigma ? 0 : static_cast<uint8_t>(std::lround(255 * std::exp(-d2 / (2 * sigma * sigma)))));
    }
  // A point's stamp depends only on its cell, and max is idempotent: stamp each cell once (key
  // scans overlap, so most of a local map's points share a cell with an earlier one).
  std::vector<bool> stamped(values_.size(), false);
  for (const auto& [x, y] : reference) {
    const int cx = static_cast<int>((x - origin_x_) / resolution), cy = static_cast<int>((y - origin_y_) / resolution);
    const size_t cell = static_cast<size_t>(cy) * width_ + cx;
    if (stamped[cell]) continue;
    stamped[cell] = true;
    const uint8_t* k = kernel.data();
    for (int dy = -reach; dy <= reach; ++dy) {
      uint8_t* row = values_.data() + static_cast<size_t>(cy + dy) * width_;
      for (int dx = -reach; dx <= reach; ++dx, ++k) row[cx + dx] = std::max(row[cx + dx], *k);
    }
  }
}

double LikelihoodGrid::score(const Points2& points) const {
  if (points.empty()) return 0.0;
  int64_t sum = 0;
  for (const auto& [x, y] : points)
    sum += at(static_cast<int>(std::floor((x - origin_x_) / resolution_)),
              static_cast<int>(std::floor((y - origin_y_) / resolution_)));
  return static_cast<double>(sum) / (255.0 * points.size());
}

Points2 thinPoints(const Points2& points, double spacing) {
  Points2 kept;
  const float spacing2 = static_cast<float>(spacing * spacing);
  float last_x = 1e30f, last_y = 1e30f;
  for (const auto& [x, y] : points) {
    if ((x - last_x) * (x - last_x) + (y - last_y) * (y - last_y) < spacing2) continue;
    kept.emplace_back(x, y);
    last_x = x, last_y = y;
  }
  return kept;
}

Points2 transformPoints(const Points2& points, const Pose2D& pose) {
  Points2 out;
  out.reserve(points.size());
  const float c = static_cast<float>(std::cos(pose.yaw)), s = static_cast<float>(std::sin(pose.yaw));
  const float tx = static_cast<float>(pose.x), ty = static_cast<float>(pose.y);
  for (const auto& [x, y] : points) out.emplace_back(tx + c * x - s * y, ty + s * x + c * y);
  return out;
}

}  // namespace mrslam::slam
