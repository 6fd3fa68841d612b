#include "mrslam/slam/stretch_reanchor.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "mrslam/slam/correlative_matcher.h"

namespace mrslam::slam {
namespace {

// rad: near where the stretch is, the best pose within this turn (and `kHereXy`) is what the
// turned pose must beat: the stretch's own placement, searched a little so that a stretch
// already right is not judged by a cell's offset.
constexpr double kHereYaw = 0.26;
constexpr double kHereXy = 0.5;

// Node `pivot`'s frame: the stretch's points (nodes [first, last)) within `max_range` of the
// pivot, thinned to the grid.
Points2 stretchCloud(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses, size_t first,
                     size_t last, size_t pivot, const StretchReanchorParams& params) {
  Points2 cloud;
  const Pose2D to_pivot = poses[pivot].inverse();
  const auto range2 = static_cast<float>(params.max_range * params.max_range);
  for (size_t k = first; k < last; ++k)
    for (const auto& [x, y] : transformPoints(*scans[k], to_pivot.compose(poses[k])))
      if (x * x + y * y <= range2) cloud.emplace_back(x, y);
  return thinPoints(cloud, params.grid_resolution);
}

// The other stretch's points (nodes [first, last)) in the map frame, within `radius` of `at`.
Points2 pointsNear(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses, size_t first, size_t last,
                   const Pose2D& at, double radius) {
  Points2 near;
  const auto r2 = static_cast<float>(radius * radius);
  const auto ax = static_cast<float>(at.x), ay = static_cast<float>(at.y);
  for (size_t k = first; k < last; ++k)
    for (const auto& [x, y] : transformPoints(*scans[k], poses[k]))
      if ((x - ax) * (x - ax) + (y - ay) * (y - ay) <= r2) near.emplace_back(x, y);
  return near;
}

}  // namespace

std::optional<Pose2D> reanchorStretch(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses,
                                      size_t split, const StretchReanchorParams& params) {
  const size_t n = scans.size();
  if (n != poses.size() || split < 1 || split >= n) return std::nullopt;
  // The smaller stretch moves; its node next to the split is the pivot of the search.
  const bool before = split <= n - split;
  const size_t first = before ? 0 : split, last = before ? split : n;
  if (last - first > params.max_nodes) return std::nullopt;
  const size_t pivot = before ? split - 1 : split;
  const Points2 cloud = stretchCloud(scans, poses, first, last, pivot, params);
  if (cloud.size() < 20) return std::nullopt;
  const double margin = params.xy + 3 * params.grid_sigma;
  const Points2 other = pointsNear(scans, poses, before ? split : 0, before ? n : split, poses[pivot],
                                   params.max_range + margin);
  if (other.empty()) return std::nullopt;
  const CorrelativeMatcher matcher(
      std::make_shared<const LikelihoodGrid>(other, params.grid_resolution, params.grid_sigma, margin));
  SearchWindow here_window;
  here_window.center = poses[pivot];
  here_window.xy = kHereXy;
  here_window.yaw = kHereYaw;
  const CorrelativeMatch here = matcher.match(cloud, here_window, 0.0);
  SearchWindow window;
  window.center = poses[pivot];
  window.xy = params.xy;
  window.yaw = M_PI;
  const double bar = std::max(params.min_score, params.min_gain * (here.found ? here.score : 0.0));
  const CorrelativeMatch best = matcher.match(cloud, window, bar);
  if (!best.found || std::abs(Pose2D::normalizeAngle(best.pose.yaw - poses[pivot].yaw)) < params.min_turn)
    return std::nullopt;
  const CorrelativeMatch rival = matcher.match(cloud, window, params.max_rival * best.score, &best.pose,
                                               CorrelativeMatcher::kRivalMinXy, CorrelativeMatcher::kRivalMinYaw);
  if (rival.found || rival.exhausted) return std::nullopt;
  // The move of the smaller stretch; the same geometry with the first node kept in place moves
  // the later stretch the other way.
  const Pose2D moved = best.pose.compose(poses[pivot].inverse());
  return before ? moved.inverse() : moved;
}

}  // namespace mrslam::slam
