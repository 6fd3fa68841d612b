#include "mrslam/slam/correlative_matcher.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace mrslam::slam {

namespace {

// The angular step that moves a point at `range` metres by about one cell.
double angularStep(double range, double resolution) {
  const double c = 1.0 - resolution * resolution / (2.0 * range * range);
  return std::acos(std::clamp(c, -1.0, 1.0));
}

// A robust "far" range of the scan: most points within it (a few stray far returns would
// otherwise make the angular step needlessly fine).
double farRange(const Points2& points) {
  std::vector<float> ranges;
  ranges.reserve(points.size());
  for (const auto& [x, y] : points) ranges.push_back(std::hypot(x, y));
  const size_t k = ranges.size() * 95 / 100;
  std::nth_element(ranges.begin(), ranges.begin() + std::min(k, ranges.size() - 1), ranges.end());
  return std::clamp<double>(ranges[std::min(k, ranges.size() - 1)], 1.0, 15.0);
}

}  // namespace

struct CorrelativeMatcher::Candidate {
  int rotation = 0;  // index into the rotated scans
  int dx = 0, dy = 0;  // offset in cells of the candidate's lowest corner
  float score = 0;
};

// The scan at one angle, as grid cells, and the box they span.
struct CorrelativeMatcher::Rotated {
  std::vector<std::pair<int, int>> cells;
  int min_x = 0, max_x = -1, min_y = 0, max_y = -1;
};

void CorrelativeMatcher::rowIndex(const Level& level, const Rotated& rotated, int32_t* out) {
  // A cell far outside the level may not fit 32 bits; no candidate holding it lies wholly inside
  // the level, so its index is never read.
  for (const auto& [cx, cy] : rotated.cells) *out++ = static_cast<int32_t>(int64_t{cy} * level.width + cx);
}

int64_t CorrelativeMatcher::sumAt(const Level& level, const Rotated& rotated, const int32_t* linear, int dx, int dy) {
  const int ox = dx + level.offset, oy = dy + level.offset;
  const int64_t width = level.width;
  int64_t sum = 0;
  // Most candidates lie wholly inside the level: those read their cells through the row-major
  // index, with no per-point bounds test nor multiply (the searches are most of a run's time;
  // same sums either way). Four sums side by side keep the loads independent.
  if (rotated.min_x + ox >= 0 && rotated.min_y + oy >= 0 && rotated.max_x + ox < level.width &&
      rotated.max_y + oy < level.height) {
    const uint8_t* const base = level.values + (oy * width + ox);
    const size_t n = rotated.cells.size();
    uint32_t s0 = 0, s1 = 0, s2 = 0, s3 = 0;  // at most 255 a cell: no overflow below 16 M points
    size_t i = 0;
    for (; i + 4 <= n; i += 4) {
      s0 += base[linear[i]];
      s1 += base[linear[i + 1]];
      s2 += base[linear[i + 2]];
      s3 += base[linear[i + 3]];
    }
    for (; i < n; ++i) s0 += base[linear[i]];
    return int64_t{s0} + s1 + s2 + s3;
  }
  for (const auto& [cx, cy] : rotated.cells) {
    const int x = cx + ox, y = cy + oy;
    if (x >= 0 && y >= 0 && x < level.width && y < level.height) sum += level.values[y * width + x];
  }
  return sum;
}

namespace {

// out[i] = max(in[i - step], in[i]) for i in [0, n + step), where in[] is n long and reads
// outside it are 0: the max over a window of two cells `step` apart, one array at a time.
void pairMax(const uint8_t* in, int n, int step, uint8_t* out) {
  const int both_from = std::min(step, n), both_to = n;  // i in [step, n): both inside
  for (int i = 0; i < both_from; ++i) out[i] = in[i];
  for (int i = step; i < both_to; ++i) out[i] = std::max(in[i - step], in[i]);
  for (int i = std::max(n, step); i < n + step; ++i) out[i] = in[i - step];
  for (int i = n; i < step; ++i) out[i] = 0;  // only when step > n: cells neither reaches
}

}  // namespace

size_t CorrelativeMatcher::bytes() const {
  size_t total = grid_->values().size();
  for (const Level& level : levels_) total += level.pooled.size();
  return total;
}

size_t CorrelativeMatcher::bytesFor(const LikelihoodGrid& grid, int levels) {
  // Level h is level h - 1 grown by 2^(h-1) cells each way (buildLevels).
  size_t total = grid.values().size();
  size_t width = grid.width(), height = grid.height();
  for (int h = 1; h < std::max(1, levels); ++h) {
    width += size_t{1} << (h - 1);
    height += size_t{1} << (h - 1);
    total += width * height;
  }
  return total;
}

CorrelativeMatcher::CorrelativeMatcher(std::shared_ptr<const LikelihoodGrid> grid, int levels)
    : grid_(std::move(grid)), levels_(std::max(1, levels)) {
  std::vector<uint8_t> row_pass;  // a cached matcher keeps only what searches read
  buildLevels(row_pass);
}

void CorrelativeMatcher::refresh() { buildLevels(row_pass_); }

void CorrelativeMatcher::buildLevels(std::vector<uint8_t>& row_pass) {
  Level& base = levels_[0];
  base.width = grid_->width();
  base.height = grid_->height();
  base.values = grid_->values().data();
  // Level h holds, at (x, y), the max of level 0 over [x, x + 2^h) x [y, y + 2^h); it also
  // covers x, y down to -(2^h - 1), where a window still reaches into the grid. It is level
  // h - 1 maxed with itself shifted by 2^(h-1), along rows then along columns. The sizes are
  // copied into locals: byte stores may alias the Level they are read from, which kept the
  // compiler from vectorising the loops (built in place without them, this took 63 % of
  // Freiburg campus's run).
  for (size_t h = 1; h < levels_.size(); ++h) {
    const int step = 1 << (h - 1);
    const int prev_width = levels_[h - 1].width, prev_height = levels_[h - 1].height;
    const uint8_t* const prev = levels_[h - 1].values;
    const int width = prev_width + step, height = prev_height + step;
    row_pass.resize(static_cast<size_t>(width) * prev_height);
    uint8_t* const rows = row_pass.data();
    for (int y = 0; y < prev_height; ++y)
      pairMax(prev + static_cast<size_t>(y) * prev_width, prev_width, step, rows + static_cast<size_t>(y) * width);
    Level& next = levels_[h];
    next.offset = (1 << h) - 1;
    next.width = width;
    next.height = height;
    next.pooled.resize(static_cast<size_t>(width) * height);
    next.values = next.pooled.data();
    uint8_t* const pooled = next.pooled.data();
    for (int y = 0; y < height; ++y) {  // row y: the max of rows y - step and y of the row pass
      uint8_t* const out = pooled + static_cast<size_t>(y) * width;
      // y - step < prev_height always; either row may lie outside the row pass.
      const uint8_t* const a = y - step >= 0 ? rows + static_cast<size_t>(y - step) * width : nullptr;
      const uint8_t* const b = y < prev_height ? rows + static_cast<size_t>(y) * width : nullptr;
      if (a && b) {
        for (int x = 0; x < width; ++x) out[x] = std::max(a[x], b[x]);
      } else if (a || b) {
        std::copy_n(a ? a : b, width, out);
      } else {
        std::fill_n(out, width, uint8_t{0});  // only when step > prev_height
      }
    }
  }
}

CorrelativeMatch CorrelativeMatcher::match(const Points2& points, const SearchWindow& window, double min_score,
                                           const Pose2D* excluded, double exclude_xy, double exclude_yaw) const {
  CorrelativeMatch result;
  if (points.empty() || grid_->empty()) return result;
  const double res = grid_->resolution();
  const double dtheta = angularStep(farRange(points), res);
  const int turns = static_cast<int>(std::ceil(window.yaw / dtheta));
  const int reach = static_cast<int>(std::ceil(window.xy / res));

  // The scan at every angle of the window, as cells of the grid with the window's centre shift.
  std::vector<double> angles;
  std::vector<Rotated> rotated;
  for (int k = -turns; k <= turns; ++k) {
    const double theta = window.center.yaw + k * dtheta;
    const double c = std::cos(theta), s = std::sin(theta);
    Rotated r;
    r.cells.reserve(points.size());
    for (const auto& [px, py] : points) {
      const double x = window.center.x + c * px - s * py, y = window.center.y + s * px + c * py;
      const int cx = static_cast<int>(std::floor((x - grid_->originX()) / res));
      const int cy = static_cast<int>(std::floor((y - grid_->originY()) / res));
      if (r.cells.empty()) r.min_x = r.max_x = cx, r.min_y = r.max_y = cy;
      r.cells.emplace_back(cx, cy);
      r.min_x = std::min(r.min_x, cx), r.max_x = std::max(r.max_x, cx);
      r.min_y = std::min(r.min_y, cy), r.max_y = std::max(r.max_y, cy);
    }
    angles.push_back(theta);
    rotated.push_back(std::move(r));
  }
  const double n = 255.0 * static_cast<double>(points.size());
  // Each rotation's row-major index on each level, made when a candidate first needs it and
  // kept one after another: a search holds only the indices of the rotations and levels it
  // reaches (most rotations are pruned at the coarse levels).
  const size_t level_count = levels_.size();
  std::vector<int32_t> linear;
  linear.reserve(rotated.size() * points.size());
  std::vector<size_t> linear_at(rotated.size() * level_count, SIZE_MAX);
  auto linearFor = [&](int rotation, int h) {
    size_t& at = linear_at[static_cast<size_t>(rotation) * level_count + static_cast<size_t>(h)];
    if (at == SIZE_MAX) {
      at = linear.size();
      linear.resize(at + points.size());
      rowIndex(levels_[h], rotated[static_cast<size_t>(rotation)], linear.data() + at);
    }
    return linear.data() + at;
  };
  size_t evaluations = 0;
  auto score = [&](const Candidate& c, int h) {
    ++evaluations;
    result.exhausted = evaluations > kMaxEvaluations;
    return static_cast<float>(sumAt(levels_[h], rotated[c.rotation], linearFor(c.rotation, h), c.dx, c.dy) / n);
  };
  // The prior's factor for a yaw offset, and its largest value over the translations of a
  // candidate covering offsets [dx, dx + size) x [dy, dy + size) (its nearest point to 0).
  auto factor = [&](double offset, double sigma) {
    if (!(sigma > 0)) return 1.0;
    return std::max(window.min_penalty, 1.0 - window.penalty_gain * (offset * offset) / (sigma * sigma));
  };
  std::vector<double> yaw_factor;
  for (double theta : angles) yaw_factor.push_back(factor(Pose2D::normalizeAngle(theta - window.center.yaw), window.sigma_yaw));
  // With an along-track sigma, offsets along and across the direction driven have factors of
  // their own. A candidate block's offsets project onto each axis as an interval, and each factor
  // is largest at the interval's point nearest 0: their product bounds every pose of the block.
  const bool directed = window.sigma_along > 0 && window.sigma_xy > 0;
  const double along_x = std::cos(window.along_direction), along_y = std::sin(window.along_direction);
  auto along_factor = [&](double offset) {
    return std::max(window.min_penalty_along,
                    1.0 - window.penalty_gain * (offset * offset) / (window.sigma_along * window.sigma_along));
  };
  auto nearest_zero = [](double lo, double hi) { return lo > 0 ? lo : (hi < 0 ? -hi : 0.0); };
  auto prior = [&](const Candidate& c, int size) {
    if (!directed) {
      if (!(window.sigma_xy > 0)) return yaw_factor[c.rotation];  // factor() would be 1
      auto nearest = [size](int lo) { return lo > 0 ? lo : (lo + size - 1 < 0 ? lo + size - 1 : 0); };
      const double d = res * std::hypot(nearest(c.dx), nearest(c.dy));
      return yaw_factor[c.rotation] * factor(d, window.sigma_xy);
    }
    double along_lo = 1e300, along_hi = -1e300, across_lo = 1e300, across_hi = -1e300;
    for (const int x : {c.dx, c.dx + size - 1})
      for (const int y : {c.dy, c.dy + size - 1}) {
        const double along = res * (x * along_x + y * along_y), across = res * (y * along_x - x * along_y);
        along_lo = std::min(along_lo, along), along_hi = std::max(along_hi, along);
        across_lo = std::min(across_lo, across), across_hi = std::max(across_hi, across);
      }
    return yaw_factor[c.rotation] * factor(nearest_zero(across_lo, across_hi), window.sigma_xy) *
           along_factor(nearest_zero(along_lo, along_hi));
  };
  auto is_excluded = [&](const Candidate& c) {
    if (!excluded) return false;
    const double x = window.center.x + c.dx * res - excluded->x, y = window.center.y + c.dy * res - excluded->y;
    return std::hypot(x, y) < exclude_xy &&
           std::abs(Pose2D::normalizeAngle(angles[c.rotation] - excluded->yaw)) < exclude_yaw;
  };

  // The coarsest level whose cells still split the window into a few candidates per angle.
  int top = 0;
  while (top + 1 < static_cast<int>(levels_.size()) && (1 << (top + 1)) <= 2 * reach + 1) ++top;
  std::vector<Candidate> start;
  for (int r = 0; r < static_cast<int>(rotated.size()); ++r)
    for (int dx = -reach; dx <= reach; dx += 1 << top)
      for (int dy = -reach; dy <= reach; dy += 1 << top) {
        Candidate c{r, dx, dy, 0};
        c.score = static_cast<float>(score(c, top) * prior(c, 1 << top));
        start.push_back(c);
      }

  float best = static_cast<float>(min_score);
  Candidate best_candidate;
  bool found = false;
  // Depth first, best first: a candidate's score at level h bounds every pose it covers.
  auto descend = [&](auto&& self, std::vector<Candidate>& candidates, int h) -> void {
    std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
    for (const Candidate& c : candidates) {
      if (result.exhausted || c.score < best || (found && c.score == best)) return;
      if (h == 0) {
        if (is_excluded(c)) continue;
        best = c.score, best_candidate = c, found = true;
        continue;
      }
      const int half = 1 << (h - 1);
      std::vector<Candidate> children;
      for (int ox : {0, half})
        for (int oy : {0, half}) {
          Candidate child{c.rotation, c.dx + ox, c.dy + oy, 0};
          if (child.dx > reach || child.dy > reach) continue;
          child.score = static_cast<float>(score(child, h - 1) * prior(child, half));
          children.push_back(child);
        }
      self(self, children, h - 1);
    }
  };
  descend(descend, start, top);
  if (!found || result.exhausted) return result;
  result.found = true;
  result.score = best;
  result.pose = {window.center.x + best_candidate.dx * res, window.center.y + best_candidate.dy * res,
                 Pose2D::normalizeAngle(angles[best_candidate.rotation])};
  return result;
}

}  // namespace mrslam::slam
