// A 2D pose graph and the solver seam behind it. Nodes are poses in the map frame; an edge
// says where node `to` is in the frame of node `from`, with an information matrix. Edges from
// the local tracker (consecutive nodes) are trusted; loop closures may be wrong, so their cost
// goes through a robust loss and the graph can drop the ones the optimum disagrees with.
//
// The solver is an interface (as slam_toolbox keeps its solver behind a plugin seam): the
// Ceres solver (robust loss, sparse Cholesky) is the default; MRPT's sparse Levenberg-Marquardt
// (optimize_graph_spa_levmarq, no robust loss) is the alternative measured beside it.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "mrslam/grid.h"

namespace mrslam::slam {

struct PoseGraphEdge {
  int from = 0, to = 0;
  Pose2D measurement;  // pose of `to` in the frame of `from`
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();
  bool loop_closure = false;  // robust loss; may be found wrong and dropped
  double drift_factor = 1.0;  // a tracker edge drifts as much as this many times its length
                              // would (graphDistances): > 1 through a poorly matched stretch
};

struct PoseGraphSolverParams {
  int max_iterations = 50;
  double robust_scale = 1.0;  // Cauchy loss scale on loop closures, in units of their sigma
};

struct OptimizeResult {
  bool ok = false;
  std::string reason;  // why not ok (the poses are then left as they were)
  int iterations = 0;
  double initial_cost = 0, final_cost = 0;
  double milliseconds = 0;
};

class PoseGraphSolver {
 public:
  virtual ~PoseGraphSolver() = default;
  // Moves `poses` to the optimum of the edges; node 0 stays fixed (the map frame). On
  // failure (no convergence to a finite optimum) `poses` are unchanged.
  virtual OptimizeResult optimize(std::vector<Pose2D>& poses, const std::vector<PoseGraphEdge>& edges) = 0;
  virtual std::string name() const = 0;
};

// "ceres" or "mrpt"; throws std::invalid_argument for another name.
std::unique_ptr<PoseGraphSolver> makePoseGraphSolver(const std::string& name, const PoseGraphSolverParams& params);

// The edge's error at `poses`: (from^-1 * to) relative to the measurement, as (x, y, yaw).
Eigen::Vector3d edgeError(const std::vector<Pose2D>& poses, const PoseGraphEdge& edge);
// Its squared Mahalanobis length e^T * information * e.
double edgeChi2(const std::vector<Pose2D>& poses, const PoseGraphEdge& edge);

// How far every node is from `source` through the graph (Dijkstra): a tracker edge counts the
// distance it travelled times its drift_factor, a loop closure `loop_length`; infinity beyond
// `cutoff`. Drift grows with the distance travelled between two poses, so this stands in for
// their relative uncertainty where the graph's own covariance would be too costly to compute
// per node.
std::vector<double> graphDistances(int nodes, const std::vector<PoseGraphEdge>& edges, int source, double loop_length,
                                   double cutoff);
// The same from the nearest of several sources (a submap's nodes).
std::vector<double> graphDistances(int nodes, const std::vector<PoseGraphEdge>& edges, const std::vector<int>& sources,
                                   double loop_length, double cutoff);

}  // namespace mrslam::slam
