#include "mrslam/slam/robot_slam.h"

namespace mrslam::slam {

RobotSlam::RobotSlam(const RobotSlamParams& params, const Pose2D& laser_in_base)
    : params_(params),
      laser_in_base_(laser_in_base),
      ekf_(params.motion),
      matcher_(params.matcher, laser_in_base),
      mapper_(params.grid, laser_in_base) {
  reset();
}

void RobotSlam::reset() {
  // The map frame is the robot's pose at its first scan, known exactly.
  ekf_.reset(Pose2D{}, Eigen::Matrix3d::Identity() * 1e-9);
  matcher_.clear();
  mapper_.clear();
  odometry_ = Pose2D{};
  gyro_yaw_ = gyro_var_ = 0;
  have_gyro_ = false;
  scans_ = 0;
  have_map_pose_ = false;
}

void RobotSlam::addOdometry(const Pose2D& increment) {
  if (std::isfinite(increment.x) && std::isfinite(increment.y) && std::isfinite(increment.yaw))
    odometry_ = odometry_.compose(increment);
}

void RobotSlam::addGyro(double yaw_increment, double variance) {
  if (!std::isfinite(yaw_increment) || !std::isfinite(variance) || variance < 0) return;
  gyro_yaw_ += yaw_increment;
  gyro_var_ += variance;
  have_gyro_ = true;
}

ScanStep RobotSlam::processScan(const LaserScan& scan) {
  ScanStep step;
  step.reason = scanProblem(scan);
  if (!step.reason.empty()) return step;
  if (validBeams(scan) < 20) {
    step.reason = "fewer than 20 valid returns";
    return step;
  }
  step.used = true;
  Pose2D u = odometry_;
  odometry_ = Pose2D{};
  const double dt = scans_ > 0 ? std::max(0.0, scan.stamp - last_stamp_) : 0.0;
  last_stamp_ = scan.stamp;
  if (std::hypot(u.x, u.y) > params_.max_odometry_jump + params_.max_odometry_speed * dt) {
    step.odometry_jump = true;
    u = Pose2D{};
  }
  if (scans_ > 0) {
    ekf_.predict(u);
    if (params_.use_imu && have_gyro_ && gyro_var_ > 0) step.imu_used = ekf_.updateYawIncrement(gyro_yaw_, gyro_var_);
  }
  gyro_yaw_ = gyro_var_ = 0;
  have_gyro_ = false;
  if (params_.use_scan_matching && !matcher_.empty()) {
    step.match = matcher_.match(scan, ekf_.pose());
    if (step.match.ok) {
      Eigen::Matrix3d R = step.match.covariance;
      // After an odometry jump the prediction is worthless: let the match decide.
      if (step.odometry_jump) ekf_.reset(ekf_.pose(), ekf_.covariance() + Eigen::Matrix3d::Identity());
      step.matched = ekf_.updatePose(step.match.pose, R);
      step.gated = !step.matched;
    }
  }
  const Pose2D pose = ekf_.pose();
  matcher_.addIfKey(scan, pose);
  const bool far_enough = !have_map_pose_ ||
      std::hypot(pose.x - last_map_pose_.x, pose.y - last_map_pose_.y) >= params_.map_update_distance ||
      std::abs(Pose2D::normalizeAngle(pose.yaw - last_map_pose_.yaw)) >= params_.map_update_angle;
  if (far_enough) {
    mapper_.insert(scan, pose);
    last_map_pose_ = pose;
    have_map_pose_ = true;
  }
  ++scans_;
  return step;
}

}  // namespace mrslam::slam
