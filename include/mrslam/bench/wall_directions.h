// How straight a map is, with no reference needed, for buildings whose walls run along two
// perpendicular directions (most offices): the scans' returns are cast along the trajectory
// into hit cells, the map is cut along each of its own wall axes into k bands holding equal
// shares of the walls (k x k regions), and each region's wall direction is found on its own.
// In a straight map they agree; a map bent by heading drift between revisits, which the
// relations the scans fix cannot see (bench/scan_relations.h), has regions turned against each
// other. Buildings whose walls are not at right angles give a spread of their own: compare
// trajectories of one log, the reference's among them, never figures of different buildings.
#pragma once

#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/laser_scan.h"

namespace mrslam::bench {

struct WallDirectionsParams {
  int regions_per_side = 3;  // k: k x k regions
  double resolution = 0.05;  // m, of the hit cells
  double max_range = 15.0;   // m: farther returns are left out (their cells smear with the angle)
  int min_hits = 3;          // returns a cell needs to count as wall
  size_t min_region_cells = 300;  // regions with fewer wall cells are left out
};

struct WallDirections {
  double axis_deg = 0;             // the whole map's wall direction, in [-45, 45)
  std::vector<double> region_deg;  // each region's direction against the axis
  double spread_deg = 0;           // largest minus smallest of region_deg
  double std_deg = 0;              // their standard deviation
};

// Walls are the cells where scans[i], taken with the laser at laser_in_base on base_link at
// poses[i], end; a direction is the angle at which the walls' cells, projected on it and on its
// perpendicular, pile up most (the sum of squared counts per cell-wide bin).
WallDirections wallDirections(const std::vector<const slam::LaserScan*>& scans, const std::vector<Pose2D>& poses,
                              const Pose2D& laser_in_base, const WallDirectionsParams& params = {});

}  // namespace mrslam::bench
