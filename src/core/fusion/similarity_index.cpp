#include "mrslam/fusion/similarity_index.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mrslam/fusion/radon.h"
#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {

SimilarityIndex::SimilarityIndex(const cv::Mat& ternary_a, const cv::Mat& ternary_b,
                                 int max_free_points, double disagreement_weight)
    : disagreement_weight_(disagreement_weight) {
  // A's classes: its cell states, and kNearOccupied for a cell next to a wall.
  lookup_a_.create(ternary_a.size(), CV_8U);
  forEachRowWithWallsNear(ternary_a, [&](int y, const uint8_t* cells, const uint8_t* near) {
    uint8_t* out = lookup_a_.ptr<uint8_t>(y);  // kUnknownCell/kFreeCell/kOccupiedCell equal our classes
    for (int x = 0; x < ternary_a.cols; ++x)
      out[x] = (near[x] & (cells[x] != kOccupiedCell)) ? static_cast<uint8_t>(kNearOccupied) : cells[x];
  });

  // B's walls, and its free cells clear of them (counted first: the subsample's stride needs
  // their number), both in raster order.
  occupied_b_ = occupiedPoints(ternary_b);
  std::vector<uint8_t> clear_free(static_cast<size_t>(ternary_b.cols));
  auto markClearFree = [&](const uint8_t* cells, const uint8_t* near) {
    for (int x = 0; x < ternary_b.cols; ++x) clear_free[x] = (cells[x] == kFreeCell) & !near[x];
  };
  size_t free_total = 0;
  forEachRowWithWallsNear(ternary_b, [&](int /*y*/, const uint8_t* cells, const uint8_t* near) {
    markClearFree(cells, near);
    for (int x = 0; x < ternary_b.cols; ++x) free_total += clear_free[x];
  });
  const size_t stride =
      max_free_points > 0 ? std::max<size_t>(1, (free_total + max_free_points - 1) / max_free_points) : 1;
  free_b_.reserve(free_total / stride + 1);
  size_t countdown = 1;  // keeps the 1st, (stride+1)th, ... free cell in raster order
  forEachRowWithWallsNear(ternary_b, [&](int y, const uint8_t* cells, const uint8_t* near) {
    markClearFree(cells, near);
    keepEveryStrideth(clear_free.data(), ternary_b.cols, y, stride, countdown, free_b_);
  });
  for (const auto& p : occupied_b_) center_b_ += cv::Point2d(p);
  if (!occupied_b_.empty()) center_b_ /= static_cast<double>(occupied_b_.size());
  free_weight_ = free_b_.empty() ? 0.0 : static_cast<double>(free_total) / free_b_.size();
}

void SimilarityIndex::accumulate(const std::vector<cv::Point2f>& points,
                                 const CellTransform& transform, bool occupied, int radius,
                                 std::vector<SimilarityCounts>& per_offset) const {
  const int side = 2 * radius + 1;
  const double c = std::cos(transform.theta), s = std::sin(transform.theta);
  const int rows = lookup_a_.rows, cols = lookup_a_.cols;
  // Per offset, counts of the classes of A met by the points: [unknown, free, occ, near].
  std::vector<int64_t> hits(static_cast<size_t>(side) * side * 4, 0);
  for (const auto& p : points) {
    const double fx = std::floor(c * p.x - s * p.y + transform.t.x), fy = std::floor(s * p.x + c * p.y + transform.t.y);
    if (!(std::abs(fx) < 1e9 && std::abs(fy) < 1e9)) continue;  // far off A (or NaN): no int for it
    const int x0 = static_cast<int>(fx) - radius;
    const int y0 = static_cast<int>(fy) - radius;
    if (x0 + side <= 0 || y0 + side <= 0 || x0 >= cols || y0 >= rows) continue;
    if (x0 >= 0 && y0 >= 0 && x0 + side <= cols && y0 + side <= rows) {
      // The whole window inside A (most points): no per-cell bounds checks.
      int64_t* h = hits.data();
      for (int dy = 0; dy < side; ++dy) {
        const uint8_t* row = lookup_a_.ptr<uint8_t>(y0 + dy) + x0;
        for (int dx = 0; dx < side; ++dx, h += 4) ++h[row[dx]];
      }
      continue;
    }
    for (int dy = 0; dy < side; ++dy) {
      const int y = y0 + dy;
      if (y < 0 || y >= rows) continue;
      const uint8_t* row = lookup_a_.ptr<uint8_t>(y);
      int64_t* h = &hits[static_cast<size_t>(dy) * side * 4];
      for (int dx = 0; dx < side; ++dx) {
        const int x = x0 + dx;
        if (x >= 0 && x < cols) ++h[dx * 4 + row[x]];
      }
    }
  }
  const double w = occupied ? 1.0 : free_weight_;
  for (size_t i = 0; i < per_offset.size(); ++i) {
    const int64_t* h = &hits[i * 4];
    SimilarityCounts& out = per_offset[i];
    if (occupied) {
      out.occupied_agree += w * (h[kOccupied] + h[kNearOccupied]);
      out.occupied_conflict += w * h[kFree];
    } else {
      out.free_agree += w * (h[kFree] + h[kNearOccupied]);
      out.free_conflict += w * h[kOccupied];
    }
  }
}

double SimilarityIndex::lever(const CellTransform& transform) const {
  std::vector<cv::Point2d> placed, shared;
  placed.reserve(occupied_b_.size());
  for (const auto& p : occupied_b_) {
    placed.push_back(transform.apply(cv::Point2d(p)));
    const double x = std::floor(placed.back().x), y = std::floor(placed.back().y);
    if (!(x >= 0 && y >= 0 && x < lookup_a_.cols && y < lookup_a_.rows)) continue;  // outside A, or NaN
    const uint8_t cls = lookup_a_.at<uint8_t>(static_cast<int>(y), static_cast<int>(x));
    if (cls == kOccupied || cls == kNearOccupied) shared.push_back(placed.back());
  }
  if (shared.size() < 2) return std::numeric_limits<double>::infinity();
  cv::Point2d centre(0, 0);
  for (const auto& q : shared) centre += q;
  centre /= static_cast<double>(shared.size());
  double spread = 0;
  for (const auto& q : shared) spread += (q - centre).dot(q - centre);
  const double gyration = std::sqrt(spread / static_cast<double>(shared.size()));
  std::vector<double> reach;
  reach.reserve(placed.size());
  for (const auto& q : placed) reach.push_back(cv::norm(q - centre));
  const auto far = reach.begin() + static_cast<std::ptrdiff_t>(0.9 * static_cast<double>(reach.size() - 1));
  std::nth_element(reach.begin(), far, reach.end());
  return gyration > 0 ? *far / gyration : std::numeric_limits<double>::infinity();
}

SimilarityCounts SimilarityIndex::evaluate(const CellTransform& transform) const {
  return search(transform, 0, 0.0, 0).counts;
}

SearchResult SimilarityIndex::search(const CellTransform& transform, int radius,
                                     double rotation_step, int rotation_steps) const {
  SearchResult best;
  best.counts.occupied_conflict = 1e300;  // score = -inf until something is evaluated
  const int side = 2 * radius + 1;
  for (int k = -rotation_steps; k <= rotation_steps; ++k) {
    CellTransform candidate{transform.theta + k * rotation_step, transform.t};
    candidate.t += transform.apply(center_b_) - candidate.apply(center_b_);
    std::vector<SimilarityCounts> per_offset(static_cast<size_t>(side) * side);
    accumulate(occupied_b_, candidate, true, radius, per_offset);
    accumulate(free_b_, candidate, false, radius, per_offset);
    for (int dy = 0; dy < side; ++dy)
      for (int dx = 0; dx < side; ++dx) {
        const SimilarityCounts& counts = per_offset[static_cast<size_t>(dy) * side + dx];
        if (counts.score(disagreement_weight_) > best.counts.score(disagreement_weight_)) {
          best.counts = counts;
          best.transform = {candidate.theta, candidate.t + cv::Point2d(dx - radius, dy - radius)};
        }
      }
  }
  return best;
}

}  // namespace mrslam::fusion
