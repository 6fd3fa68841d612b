#include "mrslam/slam/pose_refinement.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <set>

#include "mrslam/slam/correlative_matcher.h"
#include "mrslam/slam/joint_registration.h"
#include "mrslam/slam/point_icp.h"

namespace mrslam::slam {
namespace {

// Every node's points in the map frame, one after another; `first[k]` is where node k's begin.
Points2 placedPoints(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses,
                     std::vector<size_t>& first) {
  Points2 placed;
  first.assign(scans.size() + 1, 0);
  for (size_t k = 0; k < scans.size(); ++k) {
    first[k] = placed.size();
    const double c = std::cos(poses[k].yaw), s = std::sin(poses[k].yaw);
    for (const auto& [x, y] : *scans[k])
      placed.emplace_back(static_cast<float>(poses[k].x + c * x - s * y), static_cast<float>(poses[k].y + s * x + c * y));
  }
  first[scans.size()] = placed.size();
  return placed;
}

// How far each node's points lie from it at most: a node farther than that from a box has no
// point in it.
std::vector<float> reaches(const std::vector<const Points2*>& scans) {
  std::vector<float> reach(scans.size(), 0.0f);
  for (size_t k = 0; k < scans.size(); ++k)
    for (const auto& [x, y] : *scans[k]) reach[k] = std::max(reach[k], std::hypot(x, y));
  return reach;
}

// The points of every node but `own`, placed at `poses`, within `margin` of the box around
// `scan` (already in the map frame). Placed again for each search rather than kept beside
// ICP's copy (Freiburg campus: 4.5 MB), only for the nodes that can reach the box.
Points2 pointsAround(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses,
                     const std::vector<float>& reach, size_t own, const Points2& scan, double margin) {
  float x_min = INFINITY, x_max = -INFINITY, y_min = INFINITY, y_max = -INFINITY;
  for (const auto& [x, y] : scan) {
    x_min = std::min(x_min, x), x_max = std::max(x_max, x);
    y_min = std::min(y_min, y), y_max = std::max(y_max, y);
  }
  x_min -= static_cast<float>(margin), x_max += static_cast<float>(margin);
  y_min -= static_cast<float>(margin), y_max += static_cast<float>(margin);
  Points2 around;
  for (size_t k = 0; k < scans.size(); ++k) {
    const auto px = static_cast<float>(poses[k].x), py = static_cast<float>(poses[k].y);
    if (k == own || px < x_min - reach[k] || px > x_max + reach[k] || py < y_min - reach[k] || py > y_max + reach[k])
      continue;
    for (const auto& [x, y] : transformPoints(*scans[k], poses[k]))
      if (x >= x_min && x <= x_max && y >= y_min && y <= y_max) around.emplace_back(x, y);
  }
  return around;
}

// Where the correlative matcher puts node k's scan within the reseat window around its pose on
// the other nodes' points, if that fits them clearly better than its pose does.
std::optional<Pose2D> reseat(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses,
                             const std::vector<float>& reach, size_t k, const NodeRefinementParams& params) {
  const Points2 thin = thinPoints(*scans[k], params.grid_resolution);
  if (thin.size() < static_cast<size_t>(std::max(0, params.reseat_min_points))) return std::nullopt;
  // The grid reaches past the window by the kernel's own reach (likelihood_grid.h: 3 sigma).
  const double margin = params.reseat_xy + 3 * params.grid_sigma;
  const Points2 placed = transformPoints(thin, poses[k]);
  const Points2 around = pointsAround(scans, poses, reach, k, placed, margin);
  if (around.empty()) return std::nullopt;
  auto grid = std::make_shared<const LikelihoodGrid>(around, params.grid_resolution, params.grid_sigma, margin);
  const double here = grid->score(placed);
  SearchWindow window;
  window.center = poses[k];
  window.xy = params.reseat_xy;
  window.yaw = params.reseat_yaw;
  const CorrelativeMatch best = CorrelativeMatcher(grid).match(thin, window, here + params.reseat_margin);
  if (!best.found) return std::nullopt;
  return best.pose;
}

// How far the nodes moved from `before` to `after`, root mean square (m).
double rmsMove(const std::vector<Pose2D>& before, const std::vector<Pose2D>& after) {
  double sum = 0;
  for (size_t k = 0; k < before.size(); ++k) {
    const double dx = after[k].x - before[k].x, dy = after[k].y - before[k].y;
    sum += dx * dx + dy * dy;
  }
  return std::sqrt(sum / static_cast<double>(before.size()));
}

// One round of aligning each node alone: every node against one snapshot of all the others, so
// that a node aligned early in the round does not drag the later ones. Adds the nodes placed
// only after a correlative search to `reseated`.
void alignEachNode(const std::vector<const Points2*>& scans, std::vector<Pose2D>& poses,
                   const std::vector<float>& reach, const NodeRefinementParams& params,
                   std::set<size_t>& reseated) {
  IcpSchedule schedule{params.max_correspondence, params.min_correspondence, params.max_iterations, 1};
  const size_t wanted = static_cast<size_t>(std::max(0, params.correspondence_points));
  std::vector<size_t> first;
  PointIcp icp;
  icp.setReference(placedPoints(scans, poses, first));
  std::vector<Pose2D> next = poses;
  for (size_t k = 1; k < scans.size(); ++k) {
    if (scans[k]->empty()) continue;
    const SkipRange own{first[k], first[k + 1]};
    const auto paired = [&](const IcpResult& fit) { return fit.paired && fit.goodness >= params.min_goodness; };
    // As the tracker's ICP does (scan_matcher.cpp): dense scans take turns, a share per iteration.
    schedule.decimation = wanted > 0 ? std::max<size_t>(1, (scans[k]->size() + wanted - 1) / wanted) : 1;
    IcpResult fit = icp.align(*scans[k], poses[k], schedule, own);
    if (!paired(fit) && params.reseat_xy > 0) {
      const auto seat = reseat(scans, poses, reach, k, params);
      if (!seat) continue;
      fit = icp.align(*scans[k], *seat, schedule, own);
      if (paired(fit)) reseated.insert(k);
    }
    if (!paired(fit)) continue;
    next[k] = fit.pose;
  }
  poses = std::move(next);
}

}  // namespace

int allowedRounds(const NodeRefinementParams& params, size_t nodes) {
  if (params.rounds < 1 || nodes == 0) return std::max(0, params.rounds);
  const size_t by_budget = static_cast<size_t>(std::max(0, params.node_rounds)) / nodes;
  return std::max(params.rounds, static_cast<int>(std::min<size_t>(std::max(0, params.max_rounds), by_budget)));
}

RefinedPoses refineNodePoses(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses,
                             const NodeRefinementParams& params) {
  RefinedPoses result{poses, 0};
  if (scans.size() != poses.size() || scans.size() < 2) return result;
  const std::vector<float> reach = params.reseat_xy > 0 ? reaches(scans) : std::vector<float>{};
  std::set<size_t> reseated;
  const int rounds = allowedRounds(params, scans.size());
  for (int round = 0; round < rounds; ++round) {
    const std::vector<Pose2D> before = result.poses;
    alignEachNode(scans, result.poses, reach, params, reseated);
    // Then all nodes at once: an error spanning many nodes (a bend) holds each node where its
    // neighbours are when they are aligned one by one, and moves as a whole jointly.
    for (int solve = 0; solve < params.joint_solves; ++solve) registerJointly(scans, result.poses, params.joint);
    ++result.rounds;
    if (rmsMove(before, result.poses) <= params.settled_rms) break;
  }
  result.reseated = reseated.size();
  for (size_t k = 0; k < poses.size(); ++k)
    result.moved += result.poses[k].x != poses[k].x || result.poses[k].y != poses[k].y || result.poses[k].yaw != poses[k].yaw;
  return result;
}

}  // namespace mrslam::slam
