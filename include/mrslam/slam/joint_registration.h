// All nodes' scans registered at once (multi-view registration, Lu & Milios 1997): each node's
// points are paired with their nearest point of any other node, and one least-squares problem
// over every node's pose moves them all together. Part of the final refinement
// (pose_refinement.h), after each round's node-by-node ICP.
//
// A pair counts across the wall its partner lies on (point to line, as PLICP, Censi 2008): along
// a wall the nearest point is only where the scan happened to sample it. The wall's normal comes
// from the partner's neighbours along its scan. A node whose partners' walls leave it free along
// some direction (a corridor seen by a short laser) keeps point-to-point pairs, whose pull along
// the walls holds it where the graph put it. Against point to point everywhere (the harness runs
// of the README's "Final refinement"): global error of 36 bundled runs 0.2056 -> 0.2008 m, of 36
// other draws 0.2415 -> 0.2364, of the Radish runs that hold 0.4019 -> 0.3956.
//
// Why, beside aligning each node alone (pose_refinement.h): an error that spans many nodes, a
// bend or a stretch turned as a whole, leaves each node fitting its neighbours, so node by node
// each one is held where its neighbours are and only the ends of the error move. Jointly the
// nodes move together. Intel every 5th scan bent by 2.2 degrees: 10-25 % less bend left than node
// by node; the same pairs and cost with each node solved alone (only its own block of these
// normal equations) left as much as node by node (test_pose_refinement.cpp). Figures on whole
// runs in the README ("Final refinement").
//
// Gauss-Newton with the normal equations solved by conjugate gradients (Eigen), the pairs summed
// into one 3x3 block per pair of nodes. Not Ceres, nor a sparse Cholesky: on Freiburg 079
// (121 000 pairs, 4764 unknowns, 62 500 pairs of nodes that pair) a pass over the long corridor
// ties most nodes to most others, the factor fills in to nearly dense, and a step took 2.6 s
// and 80 MB more peak memory with Eigen's simplicial LDLT, 0.5 s and 118 MB with Ceres. Conjugate
// gradients take 0.1 s; their trajectory of Intel every 5th scan lies within 2 cm of Ceres's and
// scores the same global error (0.389 m).
#pragma once

#include <cstddef>
#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/likelihood_grid.h"

namespace mrslam::slam {

struct JointRegistrationParams {
  double reach = 0.2;         // m: a point pairs with the nearest other node's point within this
  double huber = 0.05;        // m: pairs farther apart than this count linearly (Huber loss)
  int points_per_node = 60;   // about this many of each node's points are paired (0: all)
  double min_goodness = 0.5;  // share of a node's points paired, or the node is held where it is
};

struct JointRegistration {
  size_t pairs = 0;
  size_t held = 0;          // nodes held where they were (node 0, and the nodes paired too little)
  double cost_before = 0;   // Huber cost of the pairs, before and after
  double cost_after = 0;
  bool moved = false;       // false: the step found did not lower the cost, and no node moved
  size_t across_walls = 0;  // pairs counted across their partner's wall (the others point to point)
  size_t free_nodes = 0;    // nodes whose partners' walls leave them free along some direction
};

// `scans[k]` holds node k's points in its own frame and `poses[k]` its pose in the map; node 0
// stays where it is. Pairs once, at the poses given, then moves the free nodes by one
// Gauss-Newton step (more steps on the same pairs changed nothing measurable: the pairs, not the
// step, limit it; pairing again does).
JointRegistration registerJointly(const std::vector<const Points2*>& scans, std::vector<Pose2D>& poses,
                                  const JointRegistrationParams& params);

}  // namespace mrslam::slam
