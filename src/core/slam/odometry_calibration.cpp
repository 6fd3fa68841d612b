#include "mrslam/slam/odometry_calibration.h"

#include <algorithm>
#include <cmath>

namespace mrslam::slam {

double OdometryCalibration::scale() const {
  if (!params_.enabled || driven_ < params_.min_distance || !(sxx_ > 0)) return 1.0;
  return std::clamp(sxm_ / sxx_, 1.0 - params_.max_scale_error, 1.0 + params_.max_scale_error);
}

double OdometryCalibration::yawPerMetre() const {
  if (!params_.enabled || driven_ < params_.min_distance || !(sdd_ > 0)) return 0.0;
  return std::clamp(sdr_ / sdd_, -params_.max_yaw_per_m, params_.max_yaw_per_m);
}

Pose2D OdometryCalibration::correct(const Pose2D& u) const {
  const double s = scale();
  const double drift = yawPerMetre() * std::hypot(u.x, u.y);
  // The heading drifted all along the way, so the way itself bends: driven at an even rate, the
  // chord to where the robot ended turns by half the drift (5 m between scans on the Intel log:
  // 16 degrees of drift, the end 0.7 m to the side).
  const double c = std::cos(drift / 2), n = std::sin(drift / 2);
  return {s * (c * u.x - n * u.y), s * (n * u.x + c * u.y), u.yaw + drift};
}

void OdometryCalibration::learn(const Pose2D& odometry, const Pose2D& measured) {
  if (!params_.enabled) return;
  const double d = std::hypot(odometry.x, odometry.y);
  const double lambda = params_.forgetting;
  sxx_ = lambda * sxx_ + odometry.x * odometry.x;
  sxm_ = lambda * sxm_ + odometry.x * measured.x;
  sdd_ = lambda * sdd_ + d * d;
  sdr_ = lambda * sdr_ + d * Pose2D::normalizeAngle(measured.yaw - odometry.yaw);
  driven_ += d;
}

}  // namespace mrslam::slam
