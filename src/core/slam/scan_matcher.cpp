#include "mrslam/slam/scan_matcher.h"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/slam/CICP.h>

namespace mrslam::slam {

namespace {

// The scan's returns in the frame of `sensor_pose`, skipping any closer than `spacing` to the
// last one kept: dense scanners (0.35 degree beams) give many more points than ICP needs, and
// the local map's k-d tree is rebuilt with every key scan.
std::vector<std::pair<float, float>> thinnedPoints(const LaserScan& scan, const Pose2D& sensor_pose, double spacing) {
  std::vector<std::pair<float, float>> kept;
  const float spacing2 = static_cast<float>(spacing * spacing);
  float last_x = 1e30f, last_y = 1e30f;
  for (const auto& [x, y] : scanPoints(scan, sensor_pose)) {
    if ((x - last_x) * (x - last_x) + (y - last_y) * (y - last_y) < spacing2) continue;
    kept.emplace_back(x, y);
    last_x = x, last_y = y;
  }
  return kept;
}

}  // namespace

struct ScanToMapMatcher::Impl {
  mrpt::maps::CSimplePointsMap local_map;
  mrpt::slam::CICP icp;
};

ScanToMapMatcher::ScanToMapMatcher(const ScanMatcherParams& params, const Pose2D& laser_in_base)
    : params_(params), laser_in_base_(laser_in_base), impl_(std::make_unique<Impl>()) {
  auto& o = impl_->icp.options;
  o.maxIterations = static_cast<unsigned>(params.max_iterations);
  o.thresholdDist = params.max_correspondence;
  o.thresholdAng = 0.0;
  o.smallestThresholdDist = params.min_correspondence;
  o.ALFA = 0.5;
  o.corresponding_points_decimation = 1;
  o.onlyUniqueRobust = false;
}

ScanToMapMatcher::~ScanToMapMatcher() = default;

void ScanToMapMatcher::clear() {
  keys_.clear();
  impl_->local_map.clear();
}

ScanMatch ScanToMapMatcher::match(const LaserScan& scan, const Pose2D& guess) const {
  ScanMatch result;
  if (keys_.empty()) {
    result.reason = "empty local map";
    return result;
  }
  mrpt::maps::CSimplePointsMap current;
  for (const auto& [x, y] : thinnedPoints(scan, laser_in_base_, params_.min_point_spacing))
    current.insertPointFast(x, y, 0.0f);
  if (current.size() < 20) {
    result.reason = "fewer than 20 valid returns";
    return result;
  }
  mrpt::slam::CICP::TReturnInfo info;
  // The pairing decimation depends on this scan. (match() is const to callers but tunes the
  // ICP object it owns: one matcher serves one robot, from one thread.)
  impl_->icp.options.corresponding_points_decimation =
      params_.correspondence_points > 0
          ? static_cast<uint32_t>(std::max<size_t>(1, (current.size() + params_.correspondence_points - 1) / params_.correspondence_points))
          : 1;
  const auto pdf = impl_->icp.Align(&impl_->local_map, &current, mrpt::poses::CPose2D(guess.x, guess.y, guess.yaw), info);
  mrpt::poses::CPosePDFGaussian gaussian;
  gaussian.copyFrom(*pdf);
  result.goodness = info.goodness;
  result.iterations = static_cast<int>(info.nIterations);
  result.pose = {gaussian.mean.x(), gaussian.mean.y(), gaussian.mean.phi()};
  Eigen::Matrix3d cov;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) cov(r, c) = gaussian.cov(r, c) * params_.covariance_scale;
  cov(0, 0) = std::max(cov(0, 0), params_.min_sigma_xy * params_.min_sigma_xy);
  cov(1, 1) = std::max(cov(1, 1), params_.min_sigma_xy * params_.min_sigma_xy);
  cov(2, 2) = std::max(cov(2, 2), params_.min_sigma_yaw * params_.min_sigma_yaw);
  result.covariance = cov;
  if (!cov.allFinite() || !std::isfinite(result.pose.x) || !std::isfinite(result.pose.yaw)) {
    result.reason = "ICP returned a non-finite pose or covariance";
  } else if (result.goodness < params_.min_goodness) {
    result.reason = "ICP goodness " + std::to_string(result.goodness) + " below min_goodness";
  } else {
    result.ok = true;
  }
  return result;
}

bool ScanToMapMatcher::addIfKey(const LaserScan& scan, const Pose2D& pose) {
  if (!keys_.empty()) {
    const Pose2D& last = keys_.back().first;
    const bool moved = std::hypot(pose.x - last.x, pose.y - last.y) >= params_.keyframe_distance;
    const bool turned = std::abs(Pose2D::normalizeAngle(pose.yaw - last.yaw)) >= params_.keyframe_angle;
    if (!moved && !turned) return false;
  }
  auto points = thinnedPoints(scan, pose.compose(laser_in_base_), params_.min_point_spacing);
  if (points.size() < 20) return false;
  keys_.emplace_back(pose, std::move(points));
  while (static_cast<int>(keys_.size()) > std::max(1, params_.keyframes)) keys_.pop_front();
  auto& map = impl_->local_map;
  map.clear();
  for (const auto& key : keys_)
    for (const auto& p : key.second) map.insertPointFast(p.first, p.second, 0.0f);
  map.mark_as_modified();
  return true;
}

}  // namespace mrslam::slam
