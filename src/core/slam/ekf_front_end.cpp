#include "mrslam/slam/ekf_front_end.h"

namespace mrslam::slam {

void countStep(const ScanStep& step, FrontEndStats& stats) {
  ++stats.scans;
  if (!step.used) {
    ++stats.rejected;
    stats.last_problem = step.reason;
    return;
  }
  ++stats.used;
  stats.matched += step.matched;
  stats.gated += step.gated;
  stats.seeded += step.seeded;
  stats.odometry_doubted += step.odometry_doubted;
  stats.odometry_jumps += step.odometry_jump;
  stats.odometry_slips += step.odometry_slipped;
  stats.odometry_reversals += step.odometry_reversed;
  stats.odometry_missed_turns += step.odometry_missed_turn;
  stats.odometry_turns_doubted += step.odometry_turn_doubted;
  stats.seeds_alone += step.seed_alone;
  stats.few_returns += step.few_returns;
  stats.searches_given_up += step.searches_given_up;
  stats.gyro_set_aside += step.gyro_set_aside;
  if (!step.gyro_problem.empty()) stats.gyro_problem = step.gyro_problem;
}

EkfFrontEnd::EkfFrontEnd(const RobotSlamParams& params, const Pose2D& laser_in_base)
    : params_(params), tracker_(params, laser_in_base), mapper_(params.grid, laser_in_base) {}

void EkfFrontEnd::reset() {
  tracker_.reset();
  mapper_.clear();
  trajectory_.clear();
  stats_ = FrontEndStats{};
  have_map_pose_ = false;
}

ScanStep EkfFrontEnd::processScan(const LaserScan& scan) {
  const ScanStep step = tracker_.track(scan);
  countStep(step, stats_);
  if (!step.used) return step;
  const Pose2D pose = tracker_.filter().pose();
  trajectory_.push_back(pose);
  const bool far_enough = !have_map_pose_ ||
      std::hypot(pose.x - last_map_pose_.x, pose.y - last_map_pose_.y) >= params_.map_update_distance ||
      std::abs(Pose2D::normalizeAngle(pose.yaw - last_map_pose_.yaw)) >= params_.map_update_angle;
  if (far_enough) {
    mapper_.insert(scan, pose);
    last_map_pose_ = pose;
    have_map_pose_ = true;
  }
  return step;
}

}  // namespace mrslam::slam
