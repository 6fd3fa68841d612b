// How well a trajectory's scans agree with each other, with no reference needed: cast every
// scan from its pose into one grid, counting per cell the beams that ended there (hits) and the
// beams that passed through (misses). Where poses are wrong, walls seen from one pose are
// crossed by rays from another: `conflict` is the share of hits that fall in cells more often
// passed through than hit. Lower is more consistent.
#pragma once

#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/laser_scan.h"

namespace mrslam::bench {

struct MapConsistency {
  double conflict = 0;  // share of hits in cells passed through more often than hit, 0..1
  size_t hits = 0;
};

// scans[i] taken with the laser at laser_in_base on base_link at poses[i]; returns beyond
// max_range are left out.
MapConsistency mapConsistency(const std::vector<const slam::LaserScan*>& scans, const std::vector<Pose2D>& poses,
                              const Pose2D& laser_in_base, double resolution = 0.05, double max_range = 20.0);

}  // namespace mrslam::bench
