#include "mrslam/bench/scan_relations.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <unordered_map>

#include "mrslam/bench/cell_key.h"

namespace mrslam::bench {

namespace {

// A scan's returns in the robot frame, with the unit normal of the wall each lies on (zero
// where its neighbours along the scan do not form a line).
struct Cloud {
  std::vector<Eigen::Vector2d> points, normals;
};

// Neighbours along the scan this far apart or less describe one wall: kNormalReach, or
// kNormalSpacings beam spacings at the point's range where beams lie further apart than that
// (1-degree beams 10 m out are 17 cm apart).
constexpr double kNormalReach = 0.3;  // m
constexpr double kNormalSpacings = 3.0;
constexpr int kNormalBeams = 2;       // beams either side
// Points whose neighbours spread across the wall more than this share of along it are corners
// or clutter, not walls: they get no normal.
constexpr double kMaxFlatness = 0.1;

Cloud cloudOf(const slam::LaserScan& scan, const Pose2D& laser_in_base, double max_range) {
  Cloud cloud;
  for (const auto& [x, y] : slam::scanPoints(scan, laser_in_base)) {
    double lx, ly;
    laser_in_base.inverse().apply(x, y, lx, ly);
    if (std::hypot(lx, ly) <= max_range) cloud.points.emplace_back(x, y);
  }
  const int n = static_cast<int>(cloud.points.size());
  cloud.normals.assign(n, Eigen::Vector2d::Zero());
  const Eigen::Vector2d laser(laser_in_base.x, laser_in_base.y);
  for (int k = 0; k < n; ++k) {
    const double reach = std::max(kNormalReach, kNormalSpacings * (cloud.points[k] - laser).norm() * scan.angle_increment);
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    std::vector<Eigen::Vector2d> near;
    for (int m = std::max(0, k - kNormalBeams); m <= std::min(n - 1, k + kNormalBeams); ++m)
      if ((cloud.points[m] - cloud.points[k]).norm() <= reach) near.push_back(cloud.points[m]), mean += cloud.points[m];
    if (near.size() < 3) continue;
    mean /= static_cast<double>(near.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& p : near) cov += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(cov);
    if (eigen.eigenvalues()(0) > kMaxFlatness * kMaxFlatness * eigen.eigenvalues()(1)) continue;
    cloud.normals[k] = eigen.eigenvectors().col(0);
  }
  return cloud;
}

// The wall points of a cloud hashed on a grid of cells `cell` wide, to find each one's
// neighbours within `cell` in the 3 x 3 cells around it.
class WallGrid {
 public:
  WallGrid(const Cloud& cloud, double cell) : cloud_(cloud), cell_(cell) {
    for (size_t k = 0; k < cloud.points.size(); ++k)
      if (!cloud.normals[k].isZero()) cells_[cellKey(cellOf(cloud.points[k].x()), cellOf(cloud.points[k].y()))].push_back(k);
  }
  // The wall point nearest to p within the cell width, or -1.
  long nearest(const Eigen::Vector2d& p) const {
    const long cx = cellOf(p.x()), cy = cellOf(p.y());
    long best = -1;
    double best_d2 = cell_ * cell_;
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy) {
        const auto it = cells_.find(cellKey(cx + dx, cy + dy));
        if (it == cells_.end()) continue;
        for (size_t k : it->second) {
          const double d2 = (cloud_.points[k] - p).squaredNorm();
          if (d2 < best_d2) best_d2 = d2, best = static_cast<long>(k);
        }
      }
    return best;
  }

 private:
  long cellOf(double v) const { return static_cast<long>(std::floor(v / cell_)); }
  const Cloud& cloud_;
  double cell_;
  std::unordered_map<int64_t, std::vector<size_t>> cells_;
};

// Gauss-Newton on point-to-line distances with pairs gated at each distance in turn, coarse
// to fine, so that a seed some decimetres off still converges and the end is exact.
constexpr double kGates[] = {0.5, 0.25, 0.1, 0.05};  // m
constexpr int kMaxIterations = 30;                    // per gate
constexpr size_t kMinPairs = 20;

Eigen::Vector2d moved(const Eigen::Vector3d& x, const Eigen::Vector2d& q) {
  const double c = std::cos(x(2)), s = std::sin(x(2));
  return {c * q.x() - s * q.y() + x(0), s * q.x() + c * q.y() + x(1)};
}

// The pose, and how well the final pairs fix its translation in its weakest direction: the
// smallest eigenvalue of the sum of n n^T over the pairs' normals, per pair (0: a corridor
// with nothing across it; 0.5: walls in every direction alike).
struct Fit {
  Eigen::Vector3d x;
  double weakest = 0;
};

std::optional<Fit> pointToLine(const Cloud& a, const Cloud& b, Eigen::Vector3d x) {
  Eigen::Matrix2d spread = Eigen::Matrix2d::Zero();
  size_t last_pairs = 0;
  for (double gate : kGates) {
    const WallGrid grid(a, gate);
    for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
      Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
      Eigen::Vector3d g = Eigen::Vector3d::Zero();
      size_t pairs = 0;
      for (const auto& q : b.points) {
        const Eigen::Vector2d p = moved(x, q);
        const long m = grid.nearest(p);
        if (m < 0) continue;
        const Eigen::Vector2d& normal = a.normals[m];
        const double residual = normal.dot(p - a.points[m]);
        const Eigen::Vector2d arm = p - x.head<2>();
        const Eigen::Vector3d jacobian(normal.x(), normal.y(), normal.x() * -arm.y() + normal.y() * arm.x());
        h += jacobian * jacobian.transpose();
        g += jacobian * residual;
        ++pairs;
      }
      if (pairs < kMinPairs) return std::nullopt;
      const Eigen::Vector3d step = -h.ldlt().solve(g);
      if (!step.allFinite()) return std::nullopt;
      x += step;
      spread = h.topLeftCorner<2, 2>(), last_pairs = pairs;
      if (step.head<2>().norm() < 1e-5 && std::abs(step(2)) < 1e-6) break;
    }
  }
  return Fit{x, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(spread).eigenvalues()(0) / static_cast<double>(last_pairs)};
}

double inlierShare(const Cloud& a, const Cloud& b, const Eigen::Vector3d& x, double distance) {
  const WallGrid grid(a, std::max(distance, 0.25));
  size_t inliers = 0;
  for (const auto& q : b.points) {
    const Eigen::Vector2d p = moved(x, q);
    const long m = grid.nearest(p);
    if (m >= 0 && std::abs(a.normals[m].dot(p - a.points[m])) <= distance) ++inliers;
  }
  return b.points.empty() ? 0.0 : static_cast<double>(inliers) / static_cast<double>(b.points.size());
}

Eigen::Vector3d vectorOf(const Pose2D& p) { return {p.x, p.y, p.yaw}; }
Pose2D poseOf(const Eigen::Vector3d& x) { return {x(0), x(1), Pose2D::normalizeAngle(x(2))}; }

// At most this many candidate pairs are kept, a seeded uniform sample of all (reservoir
// sampling): a robot that circles one room for an hour pairs every scan with thousands.
constexpr size_t kMaxCandidates = 200000;

// Pairs of scans the reference puts on one place on different passes, in a seeded random
// order; `found` receives how many there were.
std::vector<std::pair<size_t, size_t>> candidatePairs(const std::vector<Pose2D>& reference, const ScanRelationParams& params,
                                                      unsigned seed, size_t& found) {
  std::vector<double> path(reference.size(), 0.0);
  for (size_t k = 1; k < reference.size(); ++k)
    path[k] = path[k - 1] + std::hypot(reference[k].x - reference[k - 1].x, reference[k].y - reference[k - 1].y);
  std::mt19937 rng(seed);
  std::vector<std::pair<size_t, size_t>> pairs;
  found = 0;
  for (size_t i = 0; i < reference.size(); ++i)
    for (size_t j = i + 1; j < reference.size(); ++j) {
      if (path[j] - path[i] < params.min_path) continue;
      if (std::hypot(reference[j].x - reference[i].x, reference[j].y - reference[i].y) > params.max_distance) continue;
      if (std::abs(Pose2D::normalizeAngle(reference[j].yaw - reference[i].yaw)) > params.max_turn) continue;
      if (++found <= kMaxCandidates) {
        pairs.emplace_back(i, j);
      } else if (const size_t slot = std::uniform_int_distribution<size_t>(0, found - 1)(rng); slot < kMaxCandidates) {
        pairs[slot] = {i, j};
      }
    }
  std::shuffle(pairs.begin(), pairs.end(), rng);
  return pairs;
}

// ICP of cloud b onto cloud a from `seed`, with the constraint test; `inlier_share` as in
// alignScans.
std::optional<Pose2D> alignClouds(const Cloud& a, const Cloud& b, const Pose2D& seed, const ScanRelationParams& params,
                                  double* inlier_share) {
  const auto fit = pointToLine(a, b, vectorOf(seed));
  if (!fit || fit->weakest < params.min_constraint) return std::nullopt;
  if (inlier_share) *inlier_share = inlierShare(a, b, fit->x, params.inlier_distance);
  return poseOf(fit->x);
}

// Cloud b's pose in cloud a's frame when the clouds fix it: ICP from `guess` and from four seeds
// around it ends at one pose with enough of b on a's walls, and a matched onto b agrees.
std::optional<Pose2D> checkedAlignment(const Cloud& a, const Cloud& b, const Pose2D& guess, const ScanRelationParams& params) {
  auto agrees = [&](const std::optional<Pose2D>& pose, const Pose2D& with, double xy, double yaw) {
    return pose && std::hypot(pose->x - with.x, pose->y - with.y) <= xy && std::abs(Pose2D::normalizeAngle(pose->yaw - with.yaw)) <= yaw;
  };
  double share = 0;
  const auto first = alignClouds(a, b, guess, params, &share);
  if (!first || share < params.min_inlier_share) return std::nullopt;
  const double dxy = params.seed_offset_xy, dyaw = params.seed_offset_yaw;
  for (const Pose2D& offset : {Pose2D{dxy, 0, dyaw}, Pose2D{-dxy, 0, -dyaw}, Pose2D{0, dxy, -dyaw}, Pose2D{0, -dxy, dyaw}})
    if (!agrees(alignClouds(a, b, guess.compose(offset), params, nullptr), *first, params.agree_xy, params.agree_yaw))
      return std::nullopt;
  // Matched the other way round, the first scan onto the second: a pose that only the second
  // scan's clutter holds (Freiburg 079, scans 3234 and 3424: 8 degrees off, from every seed) is
  // not found again from the other side.
  double reverse_share = 0;
  const auto reverse = alignClouds(b, a, guess.inverse(), params, &reverse_share);
  if (!reverse || reverse_share < params.min_inlier_share) return std::nullopt;
  if (!agrees(reverse->inverse(), *first, params.reverse_agree_xy, params.reverse_agree_yaw)) return std::nullopt;
  return first;
}

// The scans' clouds drawn at their poses, in one frame.
Cloud localCloud(const slam::RobotLog& log, const std::vector<std::pair<size_t, Pose2D>>& scans, double max_range) {
  Cloud out;
  for (const auto& [k, pose] : scans) {
    const Cloud c = cloudOf(log.records.at(k).scan, log.laser_in_base, max_range);
    const Eigen::Vector3d x = vectorOf(pose);
    const Eigen::Rotation2Dd turn(pose.yaw);
    for (size_t m = 0; m < c.points.size(); ++m)
      out.points.push_back(moved(x, c.points[m])), out.normals.push_back(turn * c.normals[m]);
  }
  return out;
}

}  // namespace

std::optional<Pose2D> alignScans(const slam::LaserScan& a, const slam::LaserScan& b, const Pose2D& laser_in_base,
                                 const Pose2D& seed, const ScanRelationParams& params, double* inlier_share) {
  return alignClouds(cloudOf(a, laser_in_base, params.max_range), cloudOf(b, laser_in_base, params.max_range), seed, params,
                     inlier_share);
}

std::optional<Relation> scanCheckedRelation(const slam::RobotLog& log, size_t i, size_t j, const ScanRelationParams& params) {
  // Each scan's points and wall normals once, for all seven alignments.
  const Cloud a = cloudOf(log.records.at(i).scan, log.laser_in_base, params.max_range);
  const Cloud b = cloudOf(log.records.at(j).scan, log.laser_in_base, params.max_range);
  const Pose2D guess = log.records[i].reference.inverse().compose(log.records[j].reference);
  const auto pose = checkedAlignment(a, b, guess, params);
  if (!pose) return std::nullopt;
  return Relation{i, j, *pose};
}

std::optional<Pose2D> localMapRelation(const slam::RobotLog& log, const std::vector<std::pair<size_t, Pose2D>>& scans_a,
                                       const std::vector<std::pair<size_t, Pose2D>>& scans_b, const Pose2D& guess,
                                       const ScanRelationParams& params) {
  return checkedAlignment(localCloud(log, scans_a, params.max_range), localCloud(log, scans_b, params.max_range), guess, params);
}

ScanRelations scanCheckedRelations(const slam::RobotLog& log, size_t count, unsigned seed, const ScanRelationParams& params) {
  std::vector<Pose2D> reference;
  for (const auto& record : log.records) reference.push_back(record.reference);
  ScanRelations out;
  const auto pairs = candidatePairs(reference, params, seed, out.candidates);
  for (const auto& [i, j] : pairs) {
    if (out.relations.size() >= count) break;
    ++out.tried;
    if (const auto relation = scanCheckedRelation(log, i, j, params)) out.relations.push_back(*relation);
  }
  return out;
}

}  // namespace mrslam::bench
