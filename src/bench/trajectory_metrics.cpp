#include "mrslam/bench/trajectory_metrics.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

namespace mrslam::bench {

RelationError relationError(const std::vector<Pose2D>& estimate, const std::vector<Relation>& relations) {
  RelationError e;
  double t2 = 0, r2 = 0;
  for (const Relation& relation : relations) {
    if (relation.i >= estimate.size() || relation.j >= estimate.size()) continue;
    const Pose2D d_est = estimate[relation.i].inverse().compose(estimate[relation.j]);
    const Pose2D err = relation.motion.inverse().compose(d_est);
    const double t = std::hypot(err.x, err.y), r = std::abs(err.yaw);
    e.trans_mean += t, t2 += t * t, e.rot_mean += r, r2 += r * r;
    ++e.count;
  }
  if (e.count == 0) return e;
  const double n = static_cast<double>(e.count);
  e.trans_mean /= n, e.rot_mean /= n;
  e.trans_std = std::sqrt(std::max(0.0, t2 / n - e.trans_mean * e.trans_mean));
  e.rot_std = std::sqrt(std::max(0.0, r2 / n - e.rot_mean * e.rot_mean));
  return e;
}

RelationError relationError(const std::vector<Pose2D>& estimate, const std::vector<Pose2D>& reference,
                            const std::vector<std::pair<size_t, size_t>>& pairs) {
  std::vector<Relation> relations;
  relations.reserve(pairs.size());
  for (const auto& [i, j] : pairs)
    if (i < reference.size() && j < reference.size()) relations.push_back({i, j, reference[i].inverse().compose(reference[j])});
  return relationError(estimate, relations);
}

std::vector<std::pair<size_t, size_t>> consecutivePairs(size_t n, size_t step) {
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t i = 0; i + step < n; ++i) pairs.emplace_back(i, i + step);
  return pairs;
}

std::vector<std::pair<size_t, size_t>> randomPairs(size_t n, size_t count, unsigned seed) {
  std::vector<std::pair<size_t, size_t>> pairs;
  if (n < 2) return pairs;
  std::mt19937 rng(seed);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  while (pairs.size() < count) {
    const size_t i = pick(rng), j = pick(rng);
    if (i != j) pairs.emplace_back(std::min(i, j), std::max(i, j));
  }
  return pairs;
}

Pose2D fitRigid(const std::vector<Pose2D>& from, const std::vector<Pose2D>& to) {
  const size_t n = std::min(from.size(), to.size());
  if (n < 2) throw std::invalid_argument("fitRigid needs at least two pose pairs");
  double fx = 0, fy = 0, tx = 0, ty = 0;
  for (size_t i = 0; i < n; ++i) fx += from[i].x, fy += from[i].y, tx += to[i].x, ty += to[i].y;
  fx /= n, fy /= n, tx /= n, ty /= n;
  double dot = 0, cross = 0;
  for (size_t i = 0; i < n; ++i) {
    const double ax = from[i].x - fx, ay = from[i].y - fy, bx = to[i].x - tx, by = to[i].y - ty;
    dot += ax * bx + ay * by;
    cross += ax * by - ay * bx;
  }
  const double yaw = std::atan2(cross, dot), c = std::cos(yaw), s = std::sin(yaw);
  return {tx - (c * fx - s * fy), ty - (s * fx + c * fy), yaw};
}

GlobalErrorSplit splitGlobalError(const std::vector<Pose2D>& estimate, const std::vector<Pose2D>& reference,
                                  const std::vector<std::pair<size_t, size_t>>& pairs) {
  const Pose2D frame = fitRigid(estimate, reference);
  const size_t n = std::min(estimate.size(), reference.size());
  std::vector<Pose2D> own_headings(n), own_positions(n);
  for (size_t k = 0; k < n; ++k) {
    const Pose2D placed = frame.compose(estimate[k]);
    own_headings[k] = {reference[k].x, reference[k].y, placed.yaw};
    own_positions[k] = {placed.x, placed.y, reference[k].yaw};
  }
  return {relationError(own_headings, reference, pairs).trans_mean,
          relationError(own_positions, reference, pairs).trans_mean};
}

std::vector<TrajectoryEntry> readIndexedTrajectory(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::vector<TrajectoryEntry> out;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    TrajectoryEntry e;
    if (!(fields >> e.stamp >> e.pose.x >> e.pose.y >> e.pose.yaw))
      throw std::runtime_error(path + ":" + std::to_string(number) + ": expected 'timestamp x y yaw [scan]'");
    if (!(fields >> e.scan)) e.scan = -1;
    out.push_back(e);
  }
  return out;
}

std::vector<std::pair<double, Pose2D>> readTrajectory(const std::string& path) {
  std::vector<std::pair<double, Pose2D>> out;
  for (const TrajectoryEntry& e : readIndexedTrajectory(path)) out.emplace_back(e.stamp, e.pose);
  return out;
}

}  // namespace mrslam::bench
