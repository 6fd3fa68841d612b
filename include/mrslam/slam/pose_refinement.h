// The final refinement of a pose graph's nodes, when a run ends (GraphSlam::finish()): every
// node's scan is aligned by ICP to the scans of all the other nodes as the graph placed them,
// all nodes against one snapshot per round, then all nodes at once (joint_registration.h), for a
// few rounds.
//
// Why: the tracker matched each scan to the scans before it only, and the optimised graph
// places a node where its motion edges and the loop closures compromise; neither looks at the
// scans that came after it, nor at every pass over the place at once. Aligning each scan to
// everything around it (as a multi-view registration does) takes out what is left of each
// node's own error. Loop closures against submaps did not do this: a submap is drawn with the
// errors of its own nodes (all nodes matched to every submap around them, 0.2358 -> 0.2372 m
// geometric mean of the global error over the bundled logs' 36 runs; this, 0.2358 -> 0.2191).
// Measured in the README ("Final refinement"), where it also says what it costs.
#pragma once

#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/joint_registration.h"
#include "mrslam/slam/likelihood_grid.h"

namespace mrslam::slam {

struct NodeRefinementParams {
  // Rounds (allowedRounds): `rounds` for any graph (0: off); a smaller graph up to `max_rounds`,
  // as many as `node_rounds` node alignments in all allow. A round costs about as much per node,
  // and every round moved the nodes of a slow scanner's few (every 5th scan: 90-180) by 1-6 cm
  // where the first three left a bend (Intel every 5th, phase 3: 0.44 m global error after 3
  // rounds, 0.35 after 20), while a whole log's many hardly move after three.
  int rounds = 3;
  int max_rounds = 3;
  int node_rounds = 0;
  // The refinement ends after a round that moved the nodes by at most this much (root mean
  // square, m; 0: never sooner). ICP's own noise keeps every round moving them by a few mm.
  double settled_rms = 0.0;
  double max_correspondence = 0.2;  // m: ICP's first pairing distance (halved as it settles)...
  double min_correspondence = 0.03; // m: ...down to this
  int max_iterations = 15;          // ICP's, per node and round (40: as accurate on the bundled
                                    // logs' 72 runs, Freiburg campus 1.2 s slower)
  int correspondence_points = 180;  // about this many of a scan's points paired per iteration (0: all)
  double min_goodness = 0.5;        // share of the scan's points paired at the end, or the node stays
  // A node ICP cannot pair that well is searched for by correlative matching (Olson 2009) within
  // this window around its pose, on a likelihood grid of the other nodes' points around it, and
  // ICP starts again from the best pose there when that scores at least `reseat_margin` (mean
  // likelihood, 0..1) above the node's own pose. A node the tracker turned 5-16 degrees, or
  // put a few decimetres off, lies beyond ICP's first pairing distance from its walls (Intel
  // every 5th scan, phase 0: a node 16 degrees off fitted the other scans at 0.08 m median,
  // the reference pose at 0.02 m). reseat_xy 0: off.
  double reseat_xy = 0.5;           // m either way
  double reseat_yaw = 0.35;         // rad either way (20 degrees)
  double reseat_margin = 0.1;
  double grid_resolution = 0.05;    // m, of that likelihood grid
  double grid_sigma = 0.05;         // m, its kernel
  // A scan with fewer points on that grid is not searched for: a few returns fit a cluttered
  // place somewhere wrong as well as anywhere (the tracker's seed_overrule_min_points).
  int reseat_min_points = 50;
  // After each round, this many times: all nodes registered at once (joint_registration.h),
  // each time paired again at the poses the last one left. 0: off.
  int joint_solves = 2;
  JointRegistrationParams joint;
};

struct RefinedPoses {
  std::vector<Pose2D> poses;
  int rounds = 0;       // rounds run
  size_t moved = 0;     // nodes whose pose changed, in any round, alone or jointly
  size_t reseated = 0;  // of those, nodes any round aligned only after the correlative search
};

// How many rounds `params` allow for a graph of `nodes` nodes.
int allowedRounds(const NodeRefinementParams& params, size_t nodes);

// `scans[k]` holds node k's points in its own frame and `poses[k]` its pose in the map. Node 0
// is the map's origin and stays where it is.
RefinedPoses refineNodePoses(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses,
                             const NodeRefinementParams& params);

}  // namespace mrslam::slam
