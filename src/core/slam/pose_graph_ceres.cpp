// The Ceres solver of the pose graph: one autodiff residual per edge, yaw as a plain angle
// normalised inside the residual, node 0 held constant, sparse normal Cholesky.
#include <ceres/ceres.h>

#include <array>
#include <chrono>

#include "mrslam/slam/pose_graph.h"

namespace mrslam::slam {

namespace {

template <typename T>
T normalizeAngle(const T& a) {
  const T two_pi(2.0 * M_PI);
  return a - two_pi * ceres::floor((a + T(M_PI)) / two_pi);
}

// r = sqrt(information) * [R(yaw_a)^T (p_b - p_a) - m_xy;  yaw_b - yaw_a - m_yaw]
struct EdgeResidual {
  EdgeResidual(const Pose2D& m, const Eigen::Matrix3d& sqrt_information) : m_(m), sqrt_info_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    const T c = ceres::cos(a[2]), s = ceres::sin(a[2]);
    const T dx = b[0] - a[0], dy = b[1] - a[1];
    Eigen::Matrix<T, 3, 1> e;
    e(0) = c * dx + s * dy - T(m_.x);
    e(1) = -s * dx + c * dy - T(m_.y);
    e(2) = normalizeAngle(b[2] - a[2] - T(m_.yaw));
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    r = sqrt_info_.cast<T>() * e;
    return true;
  }

  static ceres::CostFunction* create(const PoseGraphEdge& edge) {
    const Eigen::Matrix3d L = edge.information.llt().matrixL();
    return new ceres::AutoDiffCostFunction<EdgeResidual, 3, 3, 3>(new EdgeResidual(edge.measurement, L.transpose()));
  }

  Pose2D m_;
  Eigen::Matrix3d sqrt_info_;
};

class CeresPoseGraphSolver : public PoseGraphSolver {
 public:
  explicit CeresPoseGraphSolver(const PoseGraphSolverParams& params) : params_(params) {}
  std::string name() const override { return "ceres"; }

  OptimizeResult optimize(std::vector<Pose2D>& poses, const std::vector<PoseGraphEdge>& edges) override {
    const auto start = std::chrono::steady_clock::now();
    OptimizeResult result;
    if (poses.empty()) {
      result.ok = true;
      return result;
    }
    std::vector<std::array<double, 3>> state(poses.size());
    for (size_t i = 0; i < poses.size(); ++i) state[i] = {poses[i].x, poses[i].y, poses[i].yaw};
    ceres::Problem problem;
    for (const PoseGraphEdge& edge : edges) {
      if (edge.from < 0 || edge.to < 0 || edge.from >= static_cast<int>(poses.size()) ||
          edge.to >= static_cast<int>(poses.size()) || !edge.information.allFinite()) {
        result.reason = "edge " + std::to_string(edge.from) + " -> " + std::to_string(edge.to) + " is invalid";
        return result;
      }
      // The Cauchy loss caps what one wrong loop closure can pull (its sigma-scaled residual
      // beyond robust_scale counts ever less).
      ceres::LossFunction* loss =
          edge.loop_closure ? new ceres::CauchyLoss(params_.robust_scale) : nullptr;
      problem.AddResidualBlock(EdgeResidual::create(edge), loss, state[edge.from].data(), state[edge.to].data());
    }
    if (problem.HasParameterBlock(state[0].data())) problem.SetParameterBlockConstant(state[0].data());
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    options.max_num_iterations = params_.max_iterations;
    options.num_threads = 1;
    options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    result.iterations = static_cast<int>(summary.iterations.size());
    result.initial_cost = summary.initial_cost;
    result.final_cost = summary.final_cost;
    result.milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    bool finite = std::isfinite(summary.final_cost);
    for (const auto& s : state) finite = finite && std::isfinite(s[0]) && std::isfinite(s[1]) && std::isfinite(s[2]);
    if (summary.termination_type == ceres::FAILURE || !finite) {
      result.reason = "solver failed: " + summary.message;
      return result;
    }
    for (size_t i = 0; i < poses.size(); ++i) poses[i] = {state[i][0], state[i][1], Pose2D::normalizeAngle(state[i][2])};
    result.ok = true;
    return result;
  }

 private:
  PoseGraphSolverParams params_;
};

}  // namespace

std::unique_ptr<PoseGraphSolver> makeCeresPoseGraphSolver(const PoseGraphSolverParams& params) {
  return std::make_unique<CeresPoseGraphSolver>(params);
}

}  // namespace mrslam::slam
