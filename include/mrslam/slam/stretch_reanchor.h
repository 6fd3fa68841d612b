// When a run ends: a stretch of the map turned as a whole by a turn the odometry missed, put
// back against the rest of the map.
//
// Where the odometry missed a sharp turn and the scan fitted too poorly anywhere to follow it
// (ScanStep::odometry_turn_doubted), the tracker went on with the odometry's heading: the map
// before that step and the map after it are each right, turned against each other (Seattle at
// every 5th scan: the first six scans 77 degrees off, 6.7 m of global error). No loop-closure
// window reaches that far, and the final refinement's search neither (pose_refinement.h). Here
// the smaller of the two stretches, its nodes' scans as one rigid cloud, is searched for on the
// other stretch's points by the correlative matcher over every heading; it moves only when
// turned at least `min_turn` it fits clearly better than near where it is, and no distinct
// pose fits nearly as well (a corridor fits itself turned round).
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/likelihood_grid.h"

namespace mrslam::slam {

struct StretchReanchorParams {
  double grid_resolution = 0.1;  // m, of the likelihood grid searched (coarse: the cloud is large)
  double grid_sigma = 0.1;       // m, its kernel
  double max_range = 10.0;       // m: the cloud's points within this of the stretch's end node
  double xy = 3.0;               // m either way the stretch's end node may move
  double min_turn = 0.785;       // rad: a smaller turn is the loop closures' and the refinement's
  double min_gain = 2.5;         // the turned pose must fit this many times better than near here...
  double min_score = 0.3;        // ...and at least this well (mean likelihood)...
  double max_rival = 0.75;       // ...and no distinct pose this share of it
  size_t max_nodes = 60;         // a larger stretch is not searched (the search's cost grows with it)
};

// `scans[k]` holds node k's points in its own frame and `poses[k]` its pose in the map; the
// turn the odometry may have missed lies between nodes split - 1 and split. Returns the map
// frame transform to apply to nodes [split, n) (the first node stays the map's origin), or
// nothing when the stretches are not clearly turned against each other.
std::optional<Pose2D> reanchorStretch(const std::vector<const Points2*>& scans, const std::vector<Pose2D>& poses,
                                      size_t split, const StretchReanchorParams& params);

}  // namespace mrslam::slam
