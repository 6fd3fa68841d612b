#include "mrslam/slam/laser_scan.h"

#include <cmath>
#include <string>

namespace mrslam::slam {

// Compared as the ranges are stored, in single precision: a log whose no-return reading is its
// stated maximum (5.6 beside a PARAM line of 5.6) holds that reading as 5.5999999f, below the
// double 5.6, and every beam that saw nothing became a wall at the maximum range.
bool isReturn(const LaserScan& scan, float r) {
  return std::isfinite(r) && r >= static_cast<float>(scan.range_min) && r < static_cast<float>(scan.range_max);
}

bool isNoReturn(const LaserScan& scan, float r) { return !std::isnan(r) && r >= static_cast<float>(scan.range_max); }

std::string scanProblem(const LaserScan& scan) {
  if (scan.ranges.empty()) return "scan has no ranges";
  if (!std::isfinite(scan.angle_min) || !std::isfinite(scan.angle_increment) || scan.angle_increment == 0.0)
    return "scan angles are not finite or the increment is zero";
  if (std::abs(scan.angle_increment) * (scan.ranges.size() - 1) > 2.0 * M_PI + 1e-6)
    return "scan covers more than 360 degrees (" + std::to_string(scan.ranges.size()) +
           " rays disagree with the angle increment)";
  if (!std::isfinite(scan.range_max) || !(scan.range_max > scan.range_min) || scan.range_min < 0)
    return "scan range limits are invalid";
  if (!std::isfinite(scan.stamp)) return "scan time stamp is not finite";
  return "";
}

size_t validBeams(const LaserScan& scan) {
  size_t n = 0;
  for (float r : scan.ranges) n += isReturn(scan, r);
  return n;
}

std::vector<std::pair<float, float>> scanPoints(const LaserScan& scan, const Pose2D& sensor_pose) {
  std::vector<std::pair<float, float>> points;
  points.reserve(scan.ranges.size());
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    const float r = scan.ranges[i];
    if (!isReturn(scan, r)) continue;
    const double a = scan.angle_min + i * scan.angle_increment;
    double x = r * std::cos(a), y = r * std::sin(a);
    sensor_pose.apply(x, y, x, y);
    points.emplace_back(static_cast<float>(x), static_cast<float>(y));
  }
  return points;
}

}  // namespace mrslam::slam
