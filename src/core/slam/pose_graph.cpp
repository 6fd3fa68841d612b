// The pose graph's edge errors, the MRPT solver (Sparse Pose Adjustment, Levenberg-Marquardt,
// no robust loss) and the solver factory. The Ceres solver is in pose_graph_ceres.cpp.
#include "mrslam/slam/pose_graph.h"

#include <mrpt/graphs/CNetworkOfPoses.h>
#include <mrpt/graphslam/levmarq.h>

#include <chrono>
#include <limits>
#include <queue>
#include <stdexcept>

namespace mrslam::slam {

std::unique_ptr<PoseGraphSolver> makeCeresPoseGraphSolver(const PoseGraphSolverParams& params);

namespace {

class MrptPoseGraphSolver : public PoseGraphSolver {
 public:
  explicit MrptPoseGraphSolver(const PoseGraphSolverParams& params) : params_(params) {}
  std::string name() const override { return "mrpt"; }

  OptimizeResult optimize(std::vector<Pose2D>& poses, const std::vector<PoseGraphEdge>& edges) override {
    const auto start = std::chrono::steady_clock::now();
    OptimizeResult result;
    mrpt::graphs::CNetworkOfPoses2DInf graph;
    for (size_t i = 0; i < poses.size(); ++i) graph.nodes[i] = mrpt::poses::CPose2D(poses[i].x, poses[i].y, poses[i].yaw);
    graph.root = 0;
    for (const PoseGraphEdge& e : edges) {
      if (e.from < 0 || e.to < 0 || e.from >= static_cast<int>(poses.size()) || e.to >= static_cast<int>(poses.size())) {
        result.reason = "edge " + std::to_string(e.from) + " -> " + std::to_string(e.to) + " is invalid";
        return result;
      }
      mrpt::poses::CPosePDFGaussianInf pdf;
      pdf.mean = mrpt::poses::CPose2D(e.measurement.x, e.measurement.y, e.measurement.yaw);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) pdf.cov_inv(r, c) = e.information(r, c);
      graph.insertEdge(static_cast<mrpt::graphs::TNodeID>(e.from), static_cast<mrpt::graphs::TNodeID>(e.to), pdf);
    }
    mrpt::graphslam::TResultInfoSpaLevMarq info;
    mrpt::containers::yaml extra = mrpt::containers::yaml::Map();
    extra["max_iterations"] = static_cast<uint64_t>(params_.max_iterations);
    try {
      mrpt::graphslam::optimize_graph_spa_levmarq(graph, info, nullptr, extra);
    } catch (const std::exception& e) {
      result.reason = std::string("solver failed: ") + e.what();
      return result;
    }
    result.iterations = static_cast<int>(info.num_iters);
    result.final_cost = info.final_total_sq_error;
    std::vector<Pose2D> out(poses.size());
    for (size_t i = 0; i < poses.size(); ++i) {
      const auto& p = graph.nodes.at(i);
      out[i] = {p.x(), p.y(), Pose2D::normalizeAngle(p.phi())};
      if (!std::isfinite(out[i].x) || !std::isfinite(out[i].y) || !std::isfinite(out[i].yaw)) {
        result.reason = "solver returned a non-finite pose";
        return result;
      }
    }
    poses = std::move(out);
    result.ok = true;
    result.milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return result;
  }

 private:
  PoseGraphSolverParams params_;
};

}  // namespace

std::unique_ptr<PoseGraphSolver> makePoseGraphSolver(const std::string& name, const PoseGraphSolverParams& params) {
  if (name == "ceres") return makeCeresPoseGraphSolver(params);
  if (name == "mrpt") return std::make_unique<MrptPoseGraphSolver>(params);
  throw std::invalid_argument("unknown pose graph solver '" + name + "' (ceres or mrpt)");
}

Eigen::Vector3d edgeError(const std::vector<Pose2D>& poses, const PoseGraphEdge& edge) {
  const Pose2D actual = poses[edge.from].inverse().compose(poses[edge.to]);
  const Pose2D& m = edge.measurement;
  return {actual.x - m.x, actual.y - m.y, Pose2D::normalizeAngle(actual.yaw - m.yaw)};
}

double edgeChi2(const std::vector<Pose2D>& poses, const PoseGraphEdge& edge) {
  const Eigen::Vector3d e = edgeError(poses, edge);
  return e.dot(edge.information * e);
}

std::vector<double> graphDistances(int nodes, const std::vector<PoseGraphEdge>& edges, int source, double loop_length,
                                   double cutoff) {
  return graphDistances(nodes, edges, std::vector<int>{source}, loop_length, cutoff);
}

std::vector<double> graphDistances(int nodes, const std::vector<PoseGraphEdge>& edges, const std::vector<int>& sources,
                                   double loop_length, double cutoff) {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> distance(static_cast<size_t>(std::max(0, nodes)), inf);
  std::vector<std::vector<std::pair<int, double>>> adjacent(distance.size());
  for (const PoseGraphEdge& e : edges) {
    if (e.from < 0 || e.to < 0 || e.from >= nodes || e.to >= nodes) continue;
    const double length = e.loop_closure ? loop_length : e.drift_factor * std::hypot(e.measurement.x, e.measurement.y);
    adjacent[e.from].emplace_back(e.to, length);
    adjacent[e.to].emplace_back(e.from, length);
  }
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open;
  for (const int source : sources)
    if (source >= 0 && source < nodes) distance[source] = 0, open.emplace(0.0, source);
  while (!open.empty()) {
    const auto [d, node] = open.top();
    open.pop();
    if (d > distance[node] || d > cutoff) continue;
    for (const auto& [next, length] : adjacent[node])
      if (d + length < distance[next] && d + length <= cutoff) {
        distance[next] = d + length;
        open.emplace(distance[next], next);
      }
  }
  return distance;
}

}  // namespace mrslam::slam
