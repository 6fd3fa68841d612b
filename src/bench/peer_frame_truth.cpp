#include "mrslam/bench/peer_frame_truth.h"

#include <cmath>

#include "mrslam/bench/trajectory_metrics.h"

namespace mrslam::bench {

std::optional<Pose2D> frameInWorld(const RobotTrack& track, size_t min_poses, double* rms_m) {
  std::vector<Pose2D> from, to;
  for (const auto& [stamp, pose] : track.estimate) {
    const auto ref = track.reference.find(stamp);
    if (ref != track.reference.end()) from.push_back(pose), to.push_back(ref->second);
  }
  if (from.size() < std::max<size_t>(min_poses, 2)) return std::nullopt;
  const Pose2D frame = fitRigid(from, to);
  if (rms_m) {
    double sum = 0;
    for (size_t i = 0; i < from.size(); ++i) {
      double x, y;
      frame.apply(from[i].x, from[i].y, x, y);
      sum += (x - to[i].x) * (x - to[i].x) + (y - to[i].y) * (y - to[i].y);
    }
    *rms_m = std::sqrt(sum / static_cast<double>(from.size()));
  }
  return frame;
}

void pathCentre(const RobotTrack& m, double& cx, double& cy) {
  cx = cy = 0;
  for (const auto& [stamp, pose] : m.estimate) cx += pose.x, cy += pose.y;
  const double n = static_cast<double>(std::max<size_t>(1, m.estimate.size()));
  cx /= n, cy /= n;
}

FrameError frameErrorAgainst(const Pose2D& estimate, const Pose2D& truth, const RobotTrack& m) {
  double cx, cy, ex, ey, tx, ty;
  pathCentre(m, cx, cy);
  estimate.apply(cx, cy, ex, ey);
  truth.apply(cx, cy, tx, ty);
  return {std::abs(Pose2D::normalizeAngle(estimate.yaw - truth.yaw)) * 180.0 / M_PI, std::hypot(ex - tx, ey - ty), truth};
}

FrameError peerFrameError(const Pose2D& estimate, const Pose2D& n_in_world, const Pose2D& m_in_world,
                          const RobotTrack& m) {
  return frameErrorAgainst(estimate, n_in_world.inverse().compose(m_in_world), m);
}

}  // namespace mrslam::bench
