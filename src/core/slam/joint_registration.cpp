#include "mrslam/slam/joint_registration.h"

#include <Eigen/Core>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <utility>

#include "mrslam/slam/nearest_point_grid.h"

namespace mrslam::slam {
namespace {

// m: the pairing grid's cells (the size PointIcp found fastest for these point densities).
constexpr float kCell = 0.1f;
// Added to each diagonal entry of the normal equations, relative and absolute, so that they
// are always positive definite: a node seen only along one straight wall is free along it.
constexpr double kRelativeDamping = 1e-6;
constexpr double kAbsoluteDamping = 1e-9;
// The normal equations are solved by conjugate gradients, to this relative residual or this
// many iterations (Freiburg 079's 4764 unknowns: 133 iterations, 0.1 s).
constexpr double kCgTolerance = 1e-8;
constexpr int kMaxCgIterations = 300;

// A pair counts only across the wall node j's points draw at q (point to line): along a wall,
// the nearest point is wherever the scan happened to sample it, and pulling p there slides nodes
// along corridors. The wall's normal is that of q's neighbours along j's scan, up to
// kNormalNeighbours either way within kNormalRadius, where they lie along a line: the smaller
// axis of their spread at most kMaxLineSpread of the larger (else the pair counts point to
// point: a corner, clutter, a lone point).
constexpr size_t kNormalNeighbours = 4;
constexpr double kNormalRadius = 0.2;  // m
constexpr double kMaxLineSpread = 0.1;
// A node whose pairs' walls hardly face some direction (the smaller axis of the walls' summed
// normals under this share of the larger: a corridor seen by a short laser) keeps point-to-point
// pairs, whose pull along the walls holds it where the graph put it; across walls alone it
// would slide freely along them (4 m laser: consecutive-scan error of Freiburg 101 0.087 ->
// 0.104 m with point to line everywhere, 0.088 with this; README, "Final refinement").
constexpr double kMinFacedShare = 0.15;

// One of node k's points (p, in k's frame) and the nearest point of node j (q, in j's frame),
// with the normal of j's wall at q (in j's frame; zero: the pair counts point to point).
struct Pair {
  uint32_t k, j;
  float px, py, qx, qy;
  float nx = 0, ny = 0;
  bool acrossWall() const { return nx != 0 || ny != 0; }
};

// The smaller and larger eigenvalue of a symmetric 2x2 matrix [a b; b c].
std::pair<double, double> eigenvalues(double a, double b, double c) {
  const double mean = 0.5 * (a + c), half = std::sqrt(0.25 * (a - c) * (a - c) + b * b);
  return {mean - half, mean + half};
}

// The normal of the wall `scan` (in scan order) draws at its point m; zero where its neighbours
// do not lie along a line.
std::pair<float, float> wallNormal(const Points2& scan, size_t m) {
  const auto [qx, qy] = scan[m];
  double sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
  int count = 0;
  const size_t first = m >= kNormalNeighbours ? m - kNormalNeighbours : 0;
  const size_t last = std::min(scan.size(), m + kNormalNeighbours + 1);
  for (size_t i = first; i < last; ++i) {
    const double dx = scan[i].first - qx, dy = scan[i].second - qy;
    if (dx * dx + dy * dy > kNormalRadius * kNormalRadius) continue;
    sx += dx, sy += dy, sxx += dx * dx, sxy += dx * dy, syy += dy * dy, ++count;
  }
  if (count < 3) return {0.0f, 0.0f};
  const double mx = sx / count, my = sy / count;
  const double cxx = sxx / count - mx * mx, cxy = sxy / count - mx * my, cyy = syy / count - my * my;
  const auto [smaller, larger] = eigenvalues(cxx, cxy, cyy);
  if (!(larger > 0) || smaller > kMaxLineSpread * larger) return {0.0f, 0.0f};
  // The larger axis lies along the wall; the normal is square to it.
  const double along = 0.5 * std::atan2(2 * cxy, cxx - cyy);
  return {static_cast<float>(-std::sin(along)), static_cast<float>(std::cos(along))};
}

// Back to point to point for the pairs of every node whose walls leave it free along some
// direction (kMinFacedShare); returns how many nodes those are.
size_t pointToPointWhereFree(std::vector<Pair>& pairs, const std::vector<Pose2D>& poses) {
  std::vector<Eigen::Matrix2d> faced(poses.size(), Eigen::Matrix2d::Zero());
  for (const Pair& p : pairs) {
    if (!p.acrossWall()) continue;
    const double c = std::cos(poses[p.j].yaw), s = std::sin(poses[p.j].yaw);
    const Eigen::Vector2d n(c * p.nx - s * p.ny, s * p.nx + c * p.ny);
    faced[p.k] += n * n.transpose();
  }
  std::vector<char> loose(poses.size(), 0);
  for (size_t k = 0; k < poses.size(); ++k) {
    const auto [smaller, larger] = eigenvalues(faced[k](0, 0), faced[k](0, 1), faced[k](1, 1));
    loose[k] = smaller < kMinFacedShare * larger;
  }
  for (Pair& p : pairs)
    if (loose[p.k]) p.nx = p.ny = 0;
  return static_cast<size_t>(std::count(loose.begin(), loose.end(), 1));
}

struct Pairing {
  std::vector<Pair> pairs;
  std::vector<char> held;
  size_t free_nodes = 0;
};

// Pairs every node's points (about points_per_node of them) with the nearest point of another
// node, all placed at `poses`. A node that pairs fewer than min_goodness of them is held.
Pairing pairNodes(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses,
                  const JointRegistrationParams& params) {
  std::vector<size_t> first(scans.size() + 1, 0);
  std::vector<float> xs, ys;
  for (size_t k = 0; k < scans.size(); ++k) {
    first[k] = xs.size();
    for (const auto& [x, y] : transformPoints(*scans[k], poses[k])) xs.push_back(x), ys.push_back(y);
  }
  first[scans.size()] = xs.size();
  NearestPointGrid grid;
  grid.build(xs.data(), ys.data(), xs.size(), kCell);
  const auto reach = static_cast<float>(params.reach);
  const auto wanted = static_cast<size_t>(std::max(0, params.points_per_node));
  Pairing pairing;
  pairing.held.assign(scans.size(), 1);
  for (size_t k = 0; k < scans.size(); ++k) {
    const size_t count = first[k + 1] - first[k];
    if (count == 0) continue;
    const size_t step = wanted > 0 ? std::max<size_t>(1, count / wanted) : 1;
    size_t tried = 0, paired = 0;
    for (size_t i = first[k]; i < first[k + 1]; i += step) {
      ++tried;
      const auto nearest = grid.nearestExcept(xs[i], ys[i], reach, first[k], first[k + 1]);
      if (nearest.index < 0) continue;
      const auto q = static_cast<size_t>(nearest.index);
      const auto j = static_cast<size_t>(std::upper_bound(first.begin(), first.end(), q) - first.begin()) - 1;
      const auto& p_local = (*scans[k])[i - first[k]];
      const auto& q_local = (*scans[j])[q - first[j]];
      const auto [nx, ny] = wallNormal(*scans[j], q - first[j]);
      pairing.pairs.push_back({static_cast<uint32_t>(k), static_cast<uint32_t>(j), p_local.first, p_local.second,
                               q_local.first, q_local.second, nx, ny});
      ++paired;
    }
    pairing.held[k] = k == 0 || static_cast<double>(paired) < params.min_goodness * static_cast<double>(tried);
  }
  pairing.free_nodes = pointToPointWhereFree(pairing.pairs, poses);
  return pairing;
}

// A pair's residual (p placed by pose k minus q placed by pose j, or only its part along the
// wall's normal) and its Jacobians with respect to (x, y, yaw) of k and of j.
struct Linearized {
  Eigen::Vector2d r;
  Eigen::Matrix<double, 2, 3> jk, jj;
};

Linearized linearize(const Pair& p, const Pose2D& a, const Pose2D& b) {
  const double ca = std::cos(a.yaw), sa = std::sin(a.yaw), cb = std::cos(b.yaw), sb = std::sin(b.yaw);
  const Eigen::Vector2d pa(ca * p.px - sa * p.py, sa * p.px + ca * p.py);
  const Eigen::Vector2d qb(cb * p.qx - sb * p.qy, sb * p.qx + cb * p.qy);
  Linearized l;
  l.r = Eigen::Vector2d(a.x, a.y) + pa - Eigen::Vector2d(b.x, b.y) - qb;
  l.jk << 1, 0, -pa.y(), 0, 1, pa.x();
  l.jj << -1, 0, qb.y(), 0, -1, -qb.x();
  if (!p.acrossWall()) return l;
  // Along the normal n, which turns with node j: r = n . (a + pa - b - qb), where n . qb does
  // not change as j turns, so d r / d yaw_j = n' . (a + pa - b), n' being n turned 90 degrees.
  const Eigen::Vector2d n(cb * p.nx - sb * p.ny, sb * p.nx + cb * p.ny), turned(-n.y(), n.x());
  const Eigen::Vector2d from_b = Eigen::Vector2d(a.x - b.x, a.y - b.y) + pa;
  l.r = Eigen::Vector2d(n.dot(l.r), 0.0);
  l.jk << n.x(), n.y(), n.x() * -pa.y() + n.y() * pa.x(), 0, 0, 0;
  l.jj << -n.x(), -n.y(), turned.dot(from_b), 0, 0, 0;
  return l;
}

// Huber: quadratic within `delta`, linear beyond; and the weight that gives its gradient.
double huberCost(double r, double delta) { return r <= delta ? 0.5 * r * r : delta * (r - 0.5 * delta); }
double huberWeight(double r, double delta) { return r <= delta ? 1.0 : delta / r; }

double cost(const std::vector<Pair>& pairs, const std::vector<Pose2D>& poses, double delta) {
  double sum = 0;
  for (const Pair& p : pairs) sum += huberCost(linearize(p, poses[p.k], poses[p.j]).r.norm(), delta);
  return sum;
}

struct NormalEquations {
  Eigen::SparseMatrix<double> matrix;  // its lower triangle: what the solver reads
  Eigen::VectorXd gradient;
};

// The pairs' Huber-weighted normal equations over the free nodes (variable[k] >= 0), summed
// into one 3x3 block per node and per pair of nodes.
NormalEquations normalEquations(const std::vector<Pair>& pairs, const std::vector<Pose2D>& poses,
                                const std::vector<int>& variable, int free_count, double delta) {
  std::vector<Eigen::Matrix3d> diagonal(static_cast<size_t>(free_count), Eigen::Matrix3d::Zero());
  std::unordered_map<uint64_t, Eigen::Matrix3d> between;  // key: lower variable << 32 | higher
  Eigen::VectorXd gradient = Eigen::VectorXd::Zero(3 * free_count);
  for (const Pair& p : pairs) {
    const int a = variable[p.k], b = variable[p.j];
    if (a < 0 && b < 0) continue;
    const Linearized l = linearize(p, poses[p.k], poses[p.j]);
    const double w = huberWeight(l.r.norm(), delta);
    if (a >= 0) {
      diagonal[static_cast<size_t>(a)] += w * l.jk.transpose() * l.jk;
      gradient.segment<3>(3 * a) += w * l.jk.transpose() * l.r;
    }
    if (b >= 0) {
      diagonal[static_cast<size_t>(b)] += w * l.jj.transpose() * l.jj;
      gradient.segment<3>(3 * b) += w * l.jj.transpose() * l.r;
    }
    if (a < 0 || b < 0) continue;
    const bool ordered = a < b;
    const uint64_t key = (static_cast<uint64_t>(ordered ? a : b) << 32) | static_cast<uint64_t>(ordered ? b : a);
    auto [it, inserted] = between.try_emplace(key, Eigen::Matrix3d::Zero());
    it->second += ordered ? Eigen::Matrix3d(w * l.jk.transpose() * l.jj) : Eigen::Matrix3d(w * l.jj.transpose() * l.jk);
  }
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(6 * diagonal.size() + 9 * between.size());
  for (size_t v = 0; v < diagonal.size(); ++v)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c <= r; ++c) {
        const double damping = r == c ? kRelativeDamping * diagonal[v](r, r) + kAbsoluteDamping : 0.0;
        entries.emplace_back(static_cast<int>(3 * v) + r, static_cast<int>(3 * v) + c, diagonal[v](r, c) + damping);
      }
  for (const auto& [key, block] : between) {
    const auto low = static_cast<int>(key >> 32), high = static_cast<int>(key & 0xffffffffu);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) entries.emplace_back(3 * high + r, 3 * low + c, block(c, r));
  }
  NormalEquations equations{Eigen::SparseMatrix<double>(3 * free_count, 3 * free_count), std::move(gradient)};
  equations.matrix.setFromTriplets(entries.begin(), entries.end());
  return equations;
}

// The Gauss-Newton step of the free nodes; empty when it is not finite.
Eigen::VectorXd gaussNewtonStep(const NormalEquations& equations) {
  Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower> solver;
  solver.setMaxIterations(kMaxCgIterations);
  solver.setTolerance(kCgTolerance);
  solver.compute(equations.matrix);
  Eigen::VectorXd step = -solver.solve(equations.gradient);
  return step.allFinite() ? step : Eigen::VectorXd{};
}

}  // namespace

JointRegistration registerJointly(const std::vector<const Points2*>& scans, std::vector<Pose2D>& poses,
                                  const JointRegistrationParams& params) {
  JointRegistration result;
  if (scans.size() != poses.size() || scans.size() < 2) return result;
  const Pairing pairing = pairNodes(scans, poses, params);
  result.pairs = pairing.pairs.size();
  result.free_nodes = pairing.free_nodes;
  result.across_walls = static_cast<size_t>(
      std::count_if(pairing.pairs.begin(), pairing.pairs.end(), [](const Pair& p) { return p.acrossWall(); }));
  std::vector<int> variable(scans.size(), -1);
  int free_count = 0;
  for (size_t k = 0; k < scans.size(); ++k)
    if (!pairing.held[k]) variable[k] = free_count++;
  result.held = scans.size() - static_cast<size_t>(free_count);
  result.cost_before = result.cost_after = cost(pairing.pairs, poses, params.huber);
  if (free_count == 0 || pairing.pairs.empty()) return result;
  const Eigen::VectorXd step =
      gaussNewtonStep(normalEquations(pairing.pairs, poses, variable, free_count, params.huber));
  if (step.size() == 0) return result;
  std::vector<Pose2D> moved = poses;
  for (size_t k = 0; k < scans.size(); ++k) {
    if (variable[k] < 0) continue;
    const Eigen::Vector3d d = step.segment<3>(3 * variable[k]);
    moved[k] = {poses[k].x + d(0), poses[k].y + d(1), Pose2D::normalizeAngle(poses[k].yaw + d(2))};
  }
  // Gauss-Newton's step on a Huber cost can overshoot: a step that does not lower it is not taken.
  const double moved_cost = cost(pairing.pairs, moved, params.huber);
  if (!(moved_cost < result.cost_before)) return result;
  poses = std::move(moved);
  result.cost_after = moved_cost;
  result.moved = true;
  return result;
}

}  // namespace mrslam::slam
