#include "mrslam/slam/nearest_point_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mrslam::slam {

void NearestPointGrid::build(const float* xs, const float* ys, size_t n, float cell, size_t max_cells) {
  start_.clear();
  px_.clear();
  py_.clear();
  index_.clear();
  nx_ = ny_ = 0;
  float x_min = std::numeric_limits<float>::max(), y_min = x_min;
  float x_max = std::numeric_limits<float>::lowest(), y_max = x_max;
  size_t finite = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(xs[i]) || !std::isfinite(ys[i])) continue;  // never a neighbour
    x_min = std::min(x_min, xs[i]);
    x_max = std::max(x_max, xs[i]);
    y_min = std::min(y_min, ys[i]);
    y_max = std::max(y_max, ys[i]);
    ++finite;
  }
  if (finite == 0) return;
  cell_ = cell > 0 && std::isfinite(cell) ? cell : 1.0f;
  const double width = static_cast<double>(x_max) - x_min, height = static_cast<double>(y_max) - y_min;
  const double cells = (width / cell_ + 1) * (height / cell_ + 1);
  if (cells > static_cast<double>(max_cells)) cell_ = static_cast<float>(cell_ * std::sqrt(cells / max_cells) * 1.01);
  x0_ = x_min;
  y0_ = y_min;
  nx_ = static_cast<int>(width / cell_) + 1;
  ny_ = static_cast<int>(height / cell_) + 1;

  // Counting sort of the points by cell.
  std::vector<uint32_t> cell_of(n, std::numeric_limits<uint32_t>::max());
  start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(xs[i]) || !std::isfinite(ys[i])) continue;
    const int gx = std::min(nx_ - 1, static_cast<int>((xs[i] - x0_) / cell_));
    const int gy = std::min(ny_ - 1, static_cast<int>((ys[i] - y0_) / cell_));
    cell_of[i] = static_cast<uint32_t>(gy) * nx_ + gx;
    ++start_[cell_of[i] + 1];
  }
  for (size_t k = 1; k < start_.size(); ++k) start_[k] += start_[k - 1];
  px_.resize(finite);
  py_.resize(finite);
  index_.resize(finite);
  std::vector<uint32_t> next(start_.begin(), start_.end() - 1);
  for (size_t i = 0; i < n; ++i) {
    if (cell_of[i] == std::numeric_limits<uint32_t>::max()) continue;
    const uint32_t slot = next[cell_of[i]]++;
    px_[slot] = xs[i];
    py_[slot] = ys[i];
    index_[slot] = static_cast<uint32_t>(i);
  }
}

template <typename Accept>
void NearestPointGrid::scanCell(int gx, int gy, float x, float y, Accept accept, Nearest& best) const {
  const size_t k = static_cast<size_t>(gy) * nx_ + gx;
  for (uint32_t s = start_[k]; s < start_[k + 1]; ++s) {
    const float dx = px_[s] - x, dy = py_[s] - y;
    const float d = dx * dx + dy * dy;
    if (d < best.dist_sq && accept(index_[s])) {
      best.dist_sq = d;
      best.index = index_[s];
    }
  }
}

template <typename Accept>
void NearestPointGrid::scanRing(int cx, int cy, int r, float x, float y, Accept accept, Nearest& best) const {
  const int x_lo = std::max(0, cx - r), x_hi = std::min(nx_ - 1, cx + r);
  if (r == 0) {
    if (cx >= 0 && cx < nx_ && cy >= 0 && cy < ny_) scanCell(cx, cy, x, y, accept, best);
    return;
  }
  for (const int gy : {cy - r, cy + r})  // the ring's bottom and top rows
    if (gy >= 0 && gy < ny_)
      for (int gx = x_lo; gx <= x_hi; ++gx) scanCell(gx, gy, x, y, accept, best);
  const int y_lo = std::max(0, cy - r + 1), y_hi = std::min(ny_ - 1, cy + r - 1);
  for (const int gx : {cx - r, cx + r})  // its left and right columns, corners excluded
    if (gx >= 0 && gx < nx_)
      for (int gy = y_lo; gy <= y_hi; ++gy) scanCell(gx, gy, x, y, accept, best);
}

template <typename Accept>
NearestPointGrid::Nearest NearestPointGrid::nearestIf(float x, float y, float max_dist, Accept accept) const {
  Nearest best;
  if (index_.empty() || !(max_dist > 0) || !std::isfinite(x) || !std::isfinite(y)) return best;
  // No two points of a map are a thousand kilometres apart; the cap keeps the cell arithmetic
  // below within int.
  max_dist = std::min(max_dist, 1e6f);
  best.dist_sq = max_dist * max_dist;  // only strictly nearer points are taken
  const float fx = (x - x0_) / cell_, fy = (y - y0_) / cell_;
  // Far outside the grid (or beyond int): nothing can be within reach unless max_dist is huge.
  const float reach = max_dist / cell_ + 2;
  if (fx < -reach || fy < -reach || fx > nx_ + reach || fy > ny_ + reach) return best;
  const int cx = static_cast<int>(std::floor(fx)), cy = static_cast<int>(std::floor(fy));
  // Every point outside the rings searched so far is at least this far beyond their edge: the
  // query's distance to its own cell's nearest side.
  const float margin = cell_ * std::min({fx - cx, cx + 1 - fx, fy - cy, cy + 1 - fy});
  const int first = std::max({0, -cx, cx - (nx_ - 1), -cy, cy - (ny_ - 1)});  // the first ring that meets the grid
  const int last = std::max({cx, nx_ - 1 - cx, cy, ny_ - 1 - cy});           // the ring that covers all of it
  for (int r = first; r <= last; ++r) {
    scanRing(cx, cy, r, x, y, accept, best);
    const float unsearched = r * cell_ + margin;
    if (unsearched >= max_dist || (best.index >= 0 && best.dist_sq <= unsearched * unsearched)) break;
  }
  if (best.index < 0) best.dist_sq = 0;
  return best;
}

NearestPointGrid::Nearest NearestPointGrid::nearest(float x, float y, float max_dist) const {
  return nearestIf(x, y, max_dist, Any{});
}

NearestPointGrid::Nearest NearestPointGrid::nearestExcept(float x, float y, float max_dist, size_t skip_first,
                                                          size_t skip_last) const {
  // Indices are 32 bits (index_): a range that starts beyond them leaves nothing out.
  constexpr size_t kMaxIndex = std::numeric_limits<uint32_t>::max();
  if (skip_last <= skip_first || skip_first > kMaxIndex) return nearest(x, y, max_dist);
  const size_t count = std::min(skip_last - skip_first, kMaxIndex);
  return nearestIf(x, y, max_dist, Outside{static_cast<uint32_t>(skip_first), static_cast<uint32_t>(count)});
}

}  // namespace mrslam::slam
