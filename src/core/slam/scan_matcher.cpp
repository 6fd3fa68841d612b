#include "mrslam/slam/scan_matcher.h"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/slam/CICP.h>

#include "mrslam/slam/grid_indexed_points_map.h"
#include "mrslam/slam/likelihood_grid.h"

namespace mrslam::slam {

struct PointCloudAligner::Impl {
  GridIndexedPointsMap reference;
  mrpt::slam::CICP icp;
};

PointCloudAligner::PointCloudAligner(const ScanMatcherParams& params)
    : params_(params), impl_(std::make_unique<Impl>()) {
  auto& o = impl_->icp.options;
  o.maxIterations = static_cast<unsigned>(params.max_iterations);
  o.thresholdDist = params.max_correspondence;
  o.thresholdAng = 0.0;
  o.smallestThresholdDist = params.min_correspondence;
  o.ALFA = 0.5;
  o.corresponding_points_decimation = 1;
  o.onlyUniqueRobust = false;
}

PointCloudAligner::~PointCloudAligner() = default;

void PointCloudAligner::setReference(const std::vector<std::pair<float, float>>& reference) {
  auto& map = impl_->reference;
  map.clear();
  for (const auto& [x, y] : reference) map.insertPointFast(x, y, 0.0f);
  map.index();
}

bool PointCloudAligner::empty() const { return impl_->reference.empty(); }

ScanMatch PointCloudAligner::align(const std::vector<std::pair<float, float>>& points, const Pose2D& guess,
                                   double max_correspondence) const {
  ScanMatch result;
  if (empty()) {
    result.reason = "empty reference";
    return result;
  }
  mrpt::maps::CSimplePointsMap current;
  for (const auto& [x, y] : points) current.insertPointFast(x, y, 0.0f);
  if (current.size() < 20) {
    result.reason = "fewer than 20 valid returns";
    return result;
  }
  mrpt::slam::CICP::TReturnInfo info;
  // The pairing decimation depends on this scan. (align() is const to callers but tunes the
  // ICP object it owns: one aligner serves one thread.)
  impl_->icp.options.corresponding_points_decimation =
      params_.correspondence_points > 0
          ? static_cast<uint32_t>(std::max<size_t>(1, (current.size() + params_.correspondence_points - 1) / params_.correspondence_points))
          : 1;
  impl_->icp.options.thresholdDist = max_correspondence > 0 ? max_correspondence : params_.max_correspondence;
  const auto pdf = impl_->icp.Align(&impl_->reference, &current, mrpt::poses::CPose2D(guess.x, guess.y, guess.yaw), info);
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
