// Building map pairs with known ground truth from real recorded data, for the merge tests
// and the benchmark. Ground truth comes from the construction only:
//  - time windows of a corrected CARMEN log, ray-cast along the reference poses expressed in
//    a frame we choose (so the true pose of that frame is known), with a small random-walk
//    drift added so the two maps are not perfectly consistent;
//  - crops of a real map re-rasterised in a frame we choose.
#pragma once

#include <random>
#include <string>
#include <vector>

#include "mrslam/grid.h"

namespace mrslam::bench {

struct LaserScan2D {
  double timestamp = 0;
  Pose2D pose;                // reference (corrected) laser pose
  double angle_min = 0, angle_increment = 0;
  std::vector<float> ranges;
};

// FLASER lines of a CARMEN log (.log or .log.gz). Malformed lines are skipped and counted.
std::vector<LaserScan2D> readCarmenScans(const std::string& path, int* skipped_lines = nullptr);

struct RaycastParams {
  double resolution = 0.05;
  double max_range = 30.0;       // beams at or beyond this are "no return" and ignored
  double occupied_ratio = 0.2;   // occupied when >= this share of the beams reaching a cell end in it
  // Random-walk drift like a good odometry-aided SLAM front end: per metre travelled, the
  // pose error grows by a step of this standard deviation (0 for none).
  // Kept small so the ground truth stays meaningful at the 2-cell level: over 100 m of travel
  // the drift is about 1 cm and 0.06 degrees (1 sigma).
  double drift_sigma_xy = 0.001;   // m per sqrt(metre travelled)
  double drift_sigma_yaw = 0.0001; // rad per sqrt(metre travelled)
};

// Map of scans [first, last) with the poses mapped through `frame_in_world.inverse()`, i.e.
// the returned grid lives in a map frame whose pose in the log's frame is frame_in_world.
OccupancyGrid raycastMap(const std::vector<LaserScan2D>& scans, size_t first, size_t last,
                         const Pose2D& frame_in_world, const RaycastParams& params, std::mt19937& rng);

// The content of `grid` re-rasterised (nearest neighbour) in a new map frame whose pose in
// grid's map frame is `frame`, axis-aligned with that frame, same resolution.
OccupancyGrid reframeGrid(const OccupancyGrid& grid, const Pose2D& frame);

// Cells [col0, col0 + cols) x [row0, row0 + rows) of grid (row 0 = bottom), origin adjusted.
OccupancyGrid cropGrid(const OccupancyGrid& grid, int col0, int row0, int cols, int rows);

// Share of the smaller map's known cells that the other map also knows, both maps given in
// one frame (b placed by b_in_a).
double knownOverlap(const OccupancyGrid& a, const OccupancyGrid& b, const Pose2D& b_in_a);

// Trims rows/columns that are entirely unknown (keeps the map frame).
OccupancyGrid trimUnknown(const OccupancyGrid& grid);

}  // namespace mrslam::bench
