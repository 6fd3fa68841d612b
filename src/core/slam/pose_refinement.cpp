#include "mrslam/slam/pose_refinement.h"

#include <algorithm>
#include <cmath>

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

}  // namespace

RefinedPoses refineNodePoses(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses,
                             const NodeRefinementParams& params) {
  RefinedPoses result{poses, 0};
  if (scans.size() != poses.size() || scans.size() < 2) return result;
  IcpSchedule schedule{params.max_correspondence, params.min_correspondence, params.max_iterations, 1};
  const size_t wanted = static_cast<size_t>(std::max(0, params.correspondence_points));
  for (int round = 0; round < params.rounds; ++round) {
    // One snapshot per round: a node aligned early in the round does not drag the later ones.
    std::vector<size_t> first;
    PointIcp icp;
    icp.setReference(placedPoints(scans, result.poses, first));
    std::vector<Pose2D> next = result.poses;
    result.moved = 0;
    for (size_t k = 1; k < scans.size(); ++k) {
      if (scans[k]->empty()) continue;
      // As the tracker's ICP does (scan_matcher.cpp): dense scans take turns, a share per iteration.
      schedule.decimation = wanted > 0 ? std::max<size_t>(1, (scans[k]->size() + wanted - 1) / wanted) : 1;
      const IcpResult fit = icp.align(*scans[k], result.poses[k], schedule, SkipRange{first[k], first[k + 1]});
      if (!fit.paired || !(fit.goodness >= params.min_goodness)) continue;
      next[k] = fit.pose;
      ++result.moved;
    }
    result.poses = std::move(next);
  }
  return result;
}

}  // namespace mrslam::slam
