#include "mrslam/slam/sensor_mount.h"

#include <algorithm>
#include <cmath>

namespace mrslam::slam {

std::optional<LaserMount> laserMount(const Eigen::Quaterniond& rotation, double x, double y, std::string* problem) {
  const auto refuse = [&](const std::string& why) -> std::optional<LaserMount> {
    if (problem) *problem = why;
    return std::nullopt;
  };
  if (!rotation.coeffs().allFinite() || !(rotation.norm() > 0) || !std::isfinite(x) || !std::isfinite(y))
    return refuse("the laser's transform is not finite");
  const Eigen::Matrix3d r = rotation.normalized().toRotationMatrix();
  // The scan plane's normal is the laser's z axis; its tilt is how far that leans from vertical.
  const double vertical = std::abs(r(2, 2));
  const double tilt_deg = std::acos(std::min(1.0, vertical)) * 180.0 / M_PI;
  if (tilt_deg > kMaxLaserTiltDeg)
    return refuse("the laser's scan plane is tilted " + std::to_string(static_cast<int>(std::lround(tilt_deg))) +
                  " degrees from the floor's (at most " + std::to_string(static_cast<int>(kMaxLaserTiltDeg)) +
                  "): it would map the floor and the ceiling, not walls");
  // Heading: where the laser's x axis points, seen from above.
  return LaserMount{Pose2D{x, y, std::atan2(r(1, 0), r(0, 0))}, r(2, 2) < 0};
}

LaserScan uprightScan(LaserScan scan) {
  // Beam k of the turned laser, at angle a in its frame, points at -a in the upright frame. Read
  // from its last beam to its first, the beams sweep the way they do from an upright laser, so
  // the front end sees the scan as an upright laser lists it (thinning and ICP's decimation
  // follow the beams' order).
  if (scan.ranges.empty()) return scan;
  scan.angle_min = -(scan.angle_min + scan.angle_increment * static_cast<double>(scan.ranges.size() - 1));
  std::reverse(scan.ranges.begin(), scan.ranges.end());
  return scan;
}

double baseYawRate(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& angular_velocity) {
  // The angular velocity in base_frame is R * w; its z component is R's last row times w.
  return rotation.normalized().toRotationMatrix().row(2).dot(angular_velocity);
}

}  // namespace mrslam::slam
