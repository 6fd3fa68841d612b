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
  return {s * u.x, s * u.y, u.yaw + yawPerMetre() * std::hypot(u.x, u.y)};
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
