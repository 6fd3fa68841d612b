#include "mrslam/slam/loop_closer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace mrslam::slam {

namespace {
constexpr double kIcpAgreeXy = 0.3;    // m: ICP may move the correlative match this far...
constexpr double kIcpAgreeYaw = 0.087; // rad: ...and turn it this much, or the pair is rejected
constexpr int kMaxGivenUpPerSubmap = 2;  // searches of one submap that may give up before it is left alone
constexpr int kSearchLevels = 7;         // the correlative search's levels (the coarsest pools 64 x 64 cells)
}  // namespace

LoopCloser::LoopCloser(const GraphParams& params, const ScanMatcherParams& icp) : params_(params), icp_params_(icp) {}

std::pair<double, double> LoopCloser::window(double distance) const {
  return {std::min(params_.loop_window_xy_max, params_.loop_window_xy + params_.loop_window_xy_per_m * distance),
          std::min(params_.loop_window_yaw_max, params_.loop_window_yaw + params_.loop_window_yaw_per_m * distance)};
}

double LoopCloser::saturationDistance() const {
  return std::max((params_.loop_window_xy_max - params_.loop_window_xy) / params_.loop_window_xy_per_m,
                  (params_.loop_window_yaw_max - params_.loop_window_yaw) / params_.loop_window_yaw_per_m);
}

const LoopCloser::Matchers& LoopCloser::matchersOf(int index, const Submap& submap) {
  auto it = cache_.find(index);
  if (it == cache_.end()) {
    Matchers m;
    auto grid = std::make_shared<const LikelihoodGrid>(submap.points(), params_.loop_resolution, params_.loop_sigma, 1.0);
    // Room first: the new matcher is never held beside a full budget (Freiburg campus, whose
    // outdoor submaps take up to 44 MB of search grids each, peaked there).
    makeRoomFor(CorrelativeMatcher::bytesFor(*grid, kSearchLevels));
    m.correlative = std::make_unique<CorrelativeMatcher>(grid, kSearchLevels);
    m.icp = std::make_unique<PointCloudAligner>(icp_params_);
    m.icp->setReference(submap.points());
    it = cache_.emplace(index, std::move(m)).first;
  }
  it->second.used = ++clock_;
  return it->second;
}

void LoopCloser::makeRoomFor(size_t bytes) {
  // Least recently used first; one matcher larger than the budget is still built (alone). Written
  // as "not within" so that a NaN budget holds one matcher rather than all of them.
  const double budget = params_.loop_matcher_cache_mb * 1024.0 * 1024.0;
  while (!cache_.empty() && !(static_cast<double>(cachedBytes() + bytes) <= budget)) {
    auto oldest = std::min_element(cache_.begin(), cache_.end(),
                                   [](const auto& a, const auto& b) { return a.second.used < b.second.used; });
    cache_.erase(oldest);
  }
}

size_t LoopCloser::cachedBytes() const {
  // The correlative grids' (the aligner's nearest-point grid is small beside them).
  size_t total = 0;
  for (const auto& [index, m] : cache_) total += m.correlative->bytes();
  return total;
}

std::optional<LoopClosure> LoopCloser::tryClosure(const Points2& points, const Pose2D& pose, int index,
                                                  const Submap& submap, const Pose2D& anchor_pose,
                                                  std::pair<double, double> window,
                                                  FrontEndStats& stats) {
  // A submap whose searches gave up scores alike everywhere (drawn along a lost track): every
  // further search of it would cost as much and end the same way. Without this, ACES without
  // odometry spent more than ten minutes on such searches.
  if (const auto it = given_up_.find(index); it != given_up_.end() && it->second >= kMaxGivenUpPerSubmap)
    return std::nullopt;  // not an attempt
  ++stats.loop_attempts;
  const auto [xy, yaw] = window;
  const Matchers& m = matchersOf(index, submap);
  const SearchWindow search{anchor_pose.inverse().compose(pose), xy, yaw};
  const CorrelativeMatch best = m.correlative->match(points, search, params_.loop_min_score);
  stats.searches_given_up += best.exhausted;
  given_up_[index] += best.exhausted;
  if (!best.found) {
    ++stats.loop_rejected_score;
    return std::nullopt;
  }
  // The best pose on the window's edge says the peak lies beyond it: the window did not hold
  // the answer, and the best inside it is only the best of the wrong poses.
  const Pose2D offset = search.center.inverse().compose(best.pose);
  const double res = params_.loop_resolution;
  if (std::abs(best.pose.x - search.center.x) > xy - 1.5 * res || std::abs(best.pose.y - search.center.y) > xy - 1.5 * res ||
      std::abs(offset.yaw) > yaw - 0.02) {
    ++stats.loop_rejected_score;
    return std::nullopt;
  }
  const double rival_floor = params_.loop_max_rival * best.score;
  const CorrelativeMatch rival =
      m.correlative->match(points, search, rival_floor, &best.pose, CorrelativeMatcher::kRivalMinXy,
                              CorrelativeMatcher::kRivalMinYaw);
  stats.searches_given_up += rival.exhausted;
  given_up_[index] += rival.exhausted;
  if (rival.found || rival.exhausted) {  // a search that gave up has not shown the match unique
    ++stats.loop_rejected_ambiguous;
    return std::nullopt;
  }
  const ScanMatch refined = m.icp->align(points, best.pose);
  const Pose2D moved = best.pose.inverse().compose(refined.pose);
  if (!refined.ok || std::hypot(moved.x, moved.y) > kIcpAgreeXy || std::abs(moved.yaw) > kIcpAgreeYaw) {
    ++stats.loop_rejected_icp;
    return std::nullopt;
  }
  const double score = m.correlative->grid().score(transformPoints(points, refined.pose));
  if (score < params_.loop_min_score) {
    ++stats.loop_rejected_icp;
    return std::nullopt;
  }
  return LoopClosure{index, refined.pose, score, rival.found ? rival.score : 0.0};
}

double LoopCloser::beyond(const Submap& submap, const Pose2D& anchor_pose, const Pose2D& pose) const {
  double cx, cy, radius;
  submap.poseCircle(cx, cy, radius);
  double x, y;
  anchor_pose.apply(cx, cy, x, y);
  return std::hypot(x - pose.x, y - pose.y) - radius;
}

std::vector<LoopClosure> LoopCloser::search(const LoopQuery& query, const std::vector<std::unique_ptr<Submap>>& submaps,
                                            const std::vector<Pose2D>& anchor_poses, FrontEndStats& stats) {
  struct Near {
    double beyond;    // distance from the node to the submap's pose circle
    double distance;  // through the graph to the submap's nearest node
    int index;
  };
  std::vector<Near> near;
  for (size_t i = 0; i < submaps.size(); ++i) {
    const Submap& s = *submaps[i];
    if (!s.finished() || s.finishedAtTravel() > query.travel - params_.loop_min_travel) continue;
    double distance = std::numeric_limits<double>::infinity();
    for (const auto& [node, pose] : s.nodeList()) distance = std::min(distance, query.graph_distance[node]);
    const double away = beyond(s, anchor_poses[i], query.pose);
    if (away <= window(distance).first + params_.loop_view_distance) near.push_back({away, distance, static_cast<int>(i)});
  }
  std::sort(near.begin(), near.end(), [](const Near& a, const Near& b) { return a.beyond < b.beyond; });
  std::vector<LoopClosure> closures;
  for (size_t k = 0; k < near.size() && static_cast<int>(k) < params_.loop_max_candidates; ++k) {
    const int i = near[k].index;
    if (auto closure = tryClosure(query.points, query.pose, i, *submaps[i], anchor_poses[i], window(near[k].distance), stats))
      closures.push_back(*closure);
  }
  return closures;
}

}  // namespace mrslam::slam
