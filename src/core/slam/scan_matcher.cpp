#include "mrslam/slam/scan_matcher.h"

#include <algorithm>
#include <cmath>

#include "mrslam/slam/likelihood_grid.h"

namespace mrslam::slam {

void PointCloudAligner::setReference(const std::vector<std::pair<float, float>>& reference) {
  icp_.setReference(reference);
}

bool PointCloudAligner::empty() const { return icp_.empty(); }

ScanMatch PointCloudAligner::align(const std::vector<std::pair<float, float>>& points, const Pose2D& guess,
                                   double max_correspondence) const {
  ScanMatch result;
  if (empty()) {
    result.reason = "empty reference";
    return result;
  }
  if (points.size() < 20) {
    result.reason = "fewer than 20 valid returns";
    return result;
  }
  IcpSchedule schedule;
  schedule.max_correspondence = max_correspondence > 0 ? max_correspondence : params_.max_correspondence;
  schedule.min_correspondence = params_.min_correspondence;
  schedule.max_iterations = params_.max_iterations;
  if (params_.correspondence_points > 0) {
    const auto wanted = static_cast<size_t>(params_.correspondence_points);
    schedule.decimation = std::max<size_t>(1, (points.size() + wanted - 1) / wanted);
  }
  const IcpResult icp = icp_.align(points, guess, schedule);
  result.goodness = icp.goodness;
  result.iterations = icp.iterations;
  result.pose = icp.pose;
  Eigen::Matrix3d cov = icp.covariance * params_.covariance_scale;
  cov(0, 0) = std::max(cov(0, 0), params_.min_sigma_xy * params_.min_sigma_xy);
  cov(1, 1) = std::max(cov(1, 1), params_.min_sigma_xy * params_.min_sigma_xy);
  cov(2, 2) = std::max(cov(2, 2), params_.min_sigma_yaw * params_.min_sigma_yaw);
  result.covariance = cov;
  if (!icp.paired) {
    result.reason = "ICP found no pairs";
  } else if (!cov.allFinite() || !std::isfinite(result.pose.x) || !std::isfinite(result.pose.yaw)) {
    result.reason = "ICP returned a non-finite pose or covariance";
  } else if (result.goodness < params_.min_goodness) {
    result.reason = "ICP goodness " + std::to_string(result.goodness) + " below min_goodness";
  } else {
    result.ok = true;
  }
  return result;
}

ScanToMapMatcher::ScanToMapMatcher(const ScanMatcherParams& params, const Pose2D& laser_in_base)
    : params_(params), laser_in_base_(laser_in_base), aligner_(params) {}

void ScanToMapMatcher::clear() {
  keys_.clear();
  aligner_.setReference({});
  ++version_;
}

std::vector<std::pair<float, float>> ScanToMapMatcher::localPoints() const {
  std::vector<std::pair<float, float>> points;
  for (const auto& key : keys_) points.insert(points.end(), key.second.begin(), key.second.end());
  return points;
}

std::vector<std::pair<float, float>> ScanToMapMatcher::pointsWithinPath(double max_path) const {
  if (!(max_path > 0)) return localPoints();
  std::vector<std::pair<float, float>> points;
  double path = 0;
  for (auto key = keys_.rbegin(); key != keys_.rend() && path <= max_path; ++key) {
    points.insert(points.end(), key->second.begin(), key->second.end());
    const auto older = std::next(key);
    if (older != keys_.rend()) path += std::hypot(key->first.x - older->first.x, key->first.y - older->first.y);
  }
  return points;
}

ScanMatch ScanToMapMatcher::match(const LaserScan& scan, const Pose2D& guess, double max_correspondence) const {
  if (keys_.empty()) {
    ScanMatch result;
    result.reason = "empty local map";
    return result;
  }
  // Dense scanners (0.35 degree beams) give many more points than ICP needs.
  return aligner_.align(thinPoints(scanPoints(scan, laser_in_base_), params_.min_point_spacing), guess, max_correspondence);
}

bool ScanToMapMatcher::addIfKey(const LaserScan& scan, const Pose2D& pose) {
  if (!keys_.empty()) {
    const Pose2D& last = keys_.back().first;
    const bool moved = std::hypot(pose.x - last.x, pose.y - last.y) >= params_.keyframe_distance;
    const bool turned = std::abs(Pose2D::normalizeAngle(pose.yaw - last.yaw)) >= params_.keyframe_angle;
    if (!moved && !turned) return false;
  }
  auto points = thinPoints(scanPoints(scan, pose.compose(laser_in_base_)), params_.min_point_spacing);
  if (points.size() < 20) return false;
  keys_.emplace_back(pose, std::move(points));
  while (static_cast<int>(keys_.size()) > std::max(1, params_.keyframes)) keys_.pop_front();
  aligner_.setReference(localPoints());
  ++version_;
  return true;
}

}  // namespace mrslam::slam
