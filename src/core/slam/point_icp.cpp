#include "mrslam/slam/point_icp.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

namespace mrslam::slam {
namespace {

// The pose stops moving when no coordinate changes by more than this (m, rad) in an iteration.
constexpr double kSettledStep = 1e-6;
// The pairing distance shrinks by this factor each time the pose settles.
constexpr double kShrink = 0.5;
// The covariance robustifies each pair's squared distance d² as d² / (d² + rho²), so that a
// few far pairs (a moved chair, a glass door) cannot make the pose look certain; rho in m.
constexpr double kKernelRho = 0.07;
// m: step of the central differences of that robust cost.
constexpr double kDifferenceStep = 0.01;
// Added to the information matrix's diagonal so that it always inverts (a scan of one straight
// wall leaves the pose free along it).
constexpr double kInformationFloor = 1e-6;

struct Fit {
  bool ok = false;
  Pose2D pose;
};

// The rigid pose that carries the scan points onto their pairs with the least squared error,
// in closed form: the centroids give the translation once the rotation is known, and the
// rotation is the angle of the summed cross-covariance.
template <typename Pairs>
Fit fitRigid(const Pairs& pairs) {
  Fit fit;
  if (pairs.size() < 2) return fit;
  double ref_x = 0, ref_y = 0, x = 0, y = 0;
  for (const auto& p : pairs) {
    ref_x += p.ref_x;
    ref_y += p.ref_y;
    x += p.x;
    y += p.y;
  }
  const double n = static_cast<double>(pairs.size());
  ref_x /= n, ref_y /= n, x /= n, y /= n;
  double cos_term = 0, sin_term = 0;
  for (const auto& p : pairs) {
    const double ax = p.ref_x - ref_x, ay = p.ref_y - ref_y, bx = p.x - x, by = p.y - y;
    cos_term += ax * bx + ay * by;
    sin_term += ay * bx - ax * by;
  }
  const double yaw = cos_term != 0 || sin_term != 0 ? std::atan2(sin_term, cos_term) : 0.0;
  const double c = std::cos(yaw), s = std::sin(yaw);
  fit.pose = {ref_x - (c * x - s * y), ref_y - (s * x + c * y), yaw};
  fit.ok = true;
  return fit;
}

double robustCost(double dx, double dy) {
  const double d2 = dx * dx + dy * dy;
  return d2 / (d2 + kKernelRho * kKernelRho);
}

// The inverse of J Jᵀ, J holding each pair's gradient of its robust cost with respect to the
// pose (x and y by central differences, yaw by the chain rule through the moved point).
template <typename Pairs>
Eigen::Matrix3d covariance(const Pairs& pairs, const Pose2D& pose) {
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw), h = kDifferenceStep;
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity() * kInformationFloor;
  for (const auto& p : pairs) {
    const double x = pose.x + c * p.x - s * p.y, y = pose.y + s * p.x + c * p.y;
    const double dx = p.ref_x - x, dy = p.ref_y - y;
    Eigen::Vector3d gradient;
    gradient(0) = (robustCost(dx - h, dy) - robustCost(dx + h, dy)) / (2 * h);
    gradient(1) = (robustCost(dx, dy - h) - robustCost(dx, dy + h)) / (2 * h);
    gradient(2) = gradient(0) * (-s * p.x - c * p.y) + gradient(1) * (c * p.x - s * p.y);
    information += gradient * gradient.transpose();
  }
  return information.llt().solve(Eigen::Matrix3d::Identity());
}

bool settled(const Pose2D& before, const Pose2D& after) {
  return std::abs(after.x - before.x) <= kSettledStep && std::abs(after.y - before.y) <= kSettledStep &&
         std::abs(Pose2D::normalizeAngle(after.yaw - before.yaw)) <= kSettledStep;
}

}  // namespace

void PointIcp::setReference(const std::vector<std::pair<float, float>>& points) {
  xs_.clear();
  ys_.clear();
  source_.clear();
  for (size_t i = 0; i < points.size(); ++i) {
    const auto [x, y] = points[i];
    if (!std::isfinite(x) || !std::isfinite(y)) continue;
    xs_.push_back(x);
    ys_.push_back(y);
    source_.push_back(static_cast<uint32_t>(i));  // the grid's indices are 32 bits too
  }
  // m: on the whole Freiburg 079 and Intel logs, cells of 0.03-0.2 m were all faster than a
  // k-d tree; 0.1 m was fastest (smaller cells cost more in cells visited than they save).
  constexpr float kCell = 0.1f;
  grid_.build(xs_.data(), ys_.data(), xs_.size(), kCell);
  if (xs_.empty()) return;
  const auto [x_min, x_max] = std::minmax_element(xs_.begin(), xs_.end());
  const auto [y_min, y_max] = std::minmax_element(ys_.begin(), ys_.end());
  x_min_ = *x_min, x_max_ = *x_max, y_min_ = *y_min, y_max_ = *y_max;
}

std::vector<PointIcp::Pair> PointIcp::pairs(const std::vector<std::pair<float, float>>& points, const Pose2D& pose,
                                            double reach, size_t decimation, size_t offset, SkipRange skip) const {
  std::vector<Pair> found;
  const float c = static_cast<float>(std::cos(pose.yaw)), s = static_cast<float>(std::sin(pose.yaw));
  const float tx = static_cast<float>(pose.x), ty = static_cast<float>(pose.y);
  std::vector<std::pair<float, float>> moved(points.size());
  float x_min = INFINITY, x_max = -INFINITY, y_min = INFINITY, y_max = -INFINITY;
  for (size_t i = 0; i < points.size(); ++i) {
    const auto [x, y] = points[i];
    moved[i] = {tx + c * x - s * y, ty + s * x + c * y};
    x_min = std::min(x_min, moved[i].first), x_max = std::max(x_max, moved[i].first);
    y_min = std::min(y_min, moved[i].second), y_max = std::max(y_max, moved[i].second);
  }
  if (x_min > x_max_ || x_max < x_min_ || y_min > y_max_ || y_max < y_min_) return found;
  found.reserve(points.size() / decimation + 1);
  // A hair wider for the grid, so that rounding never drops a pair the exact test keeps.
  const float grid_reach = static_cast<float>(reach) * 1.0001f + 1e-6f;
  for (size_t i = offset; i < points.size(); i += decimation) {
    const auto [x, y] = moved[i];
    const auto nearest = grid_.nearestExcept(x, y, grid_reach, skip.first, skip.last);
    if (nearest.index < 0 || !(nearest.dist_sq < reach * reach)) continue;
    const auto j = static_cast<size_t>(nearest.index);
    found.push_back({xs_[j], ys_[j], points[i].first, points[i].second});
  }
  return found;
}

IcpResult PointIcp::align(const std::vector<std::pair<float, float>>& points, const Pose2D& guess,
                          const IcpSchedule& schedule, SkipRange skip) const {
  IcpResult result;
  result.pose = guess;
  if (empty() || points.empty()) return result;
  const size_t decimation = std::max<size_t>(1, schedule.decimation);
  // The distance halves until it falls below the final one, so the final one must be above 0.
  const double final_reach = std::max(schedule.min_correspondence, 1e-6);
  double reach = schedule.max_correspondence;
  if (!std::isfinite(reach)) return result;  // it would never shrink below the final one
  // The range in xs_'s indices: the kept points from skip.first up to skip.last.
  const SkipRange kept_skip{static_cast<size_t>(std::lower_bound(source_.begin(), source_.end(), skip.first) - source_.begin()),
                            static_cast<size_t>(std::lower_bound(source_.begin(), source_.end(), skip.last) - source_.begin())};
  size_t offset = 0;
  std::vector<Pair> last_pairs;
  bool more = true;
  while (more) {
    last_pairs = pairs(points, result.pose, reach, decimation, offset, kept_skip);
    const Fit fit = fitRigid(last_pairs);
    bool approaching = fit.ok;
    if (fit.ok) {
      const bool still = settled(result.pose, fit.pose);
      result.pose = fit.pose;
      if (still) {
        reach *= kShrink;
        approaching = reach >= final_reach;
        offset = (offset + 1) % decimation;
      }
    }
    ++result.iterations;
    // Out of iterations: the distance shrinks every time until it reaches the final one.
    const bool overtime = result.iterations >= schedule.max_iterations;
    if (overtime && reach > final_reach) reach *= kShrink;
    more = (approaching && !overtime) || (overtime && reach > final_reach);
  }
  result.paired = !last_pairs.empty();
  result.goodness = static_cast<double>(decimation * last_pairs.size()) / static_cast<double>(points.size());
  if (result.paired) result.covariance = covariance(last_pairs, result.pose);
  return result;
}

}  // namespace mrslam::slam
