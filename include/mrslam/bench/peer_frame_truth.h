// Ground truth for the pose of one robot's map frame in another's, when both robots ran on time
// windows of one corrected log (the multi-robot rostest and scripts/bench_multi).
//
// The log's reference poses are one consistent trajectory in one world frame. Each robot's map
// frame is where its own filter put it, so it is placed in the world by the rigid transform
// T_N that best aligns (least squares) the poses the robot published with the reference poses of
// the same scans. The true pose of robotM/map in robotN/map is T_N^-1 * T_M; it absorbs how each
// robot defined its map frame and averages its drift over the window.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "mrslam/grid.h"

namespace mrslam::bench {

// One robot's published poses and the log's reference poses, both keyed by scan stamp (ns).
struct RobotTrack {
  std::map<uint64_t, Pose2D> estimate, reference;
};

// T_N: where the robot's map frame sits in the log's world frame; nothing when fewer than
// `min_poses` published poses have a reference. `rms_m`, if given, receives the fit's residual
// (the robot's own drift over its window): how far this truth itself can be trusted.
std::optional<Pose2D> frameInWorld(const RobotTrack& track, size_t min_poses = 20, double* rms_m = nullptr);

// Error of an estimated pose of robot M's map frame in robot N's. As in the merge benchmark the
// translation error is measured where M's map lands: at the centroid of M's trajectory (in M's
// own map frame).
struct FrameError {
  double yaw_deg = 0, metres = 0;
  Pose2D truth;  // the true pose of M's map frame in N's, T_N^-1 * T_M
};
FrameError peerFrameError(const Pose2D& estimate, const Pose2D& n_in_world, const Pose2D& m_in_world,
                          const RobotTrack& m);
// The same against a truth given directly (M's map frame in N's).
FrameError frameErrorAgainst(const Pose2D& estimate, const Pose2D& truth, const RobotTrack& m);
// The centre of M's path in M's map frame (the mean of its estimated positions): where the
// translation error is measured.
void pathCentre(const RobotTrack& m, double& cx, double& cy);

}  // namespace mrslam::bench
