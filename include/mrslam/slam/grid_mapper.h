// Log-odds occupancy grid of one robot (MRPT's COccupancyGridMap2D), growing as the robot
// explores. Exports straight into a caller's buffer (e.g. a nav_msgs/OccupancyGrid's data
// about to be published) in one pass, with no intermediate copy.
#pragma once

#include <cstdint>
#include <memory>

#include "mrslam/grid.h"
#include "mrslam/slam/laser_scan.h"

namespace mrslam::slam {

struct GridMapperParams {
  double resolution = 0.05;            // m per cell
  double initial_size = 20.0;          // m, side of the initial square map (it grows as needed)
  double max_insert_range = 30.0;      // m, returns beyond this are not inserted
  double no_return_range = 5.0;        // m: a beam with no return clears free space this far (0: not at all)
  double occupied_update = 0.65;       // probability of one hit (MRPT maxOccupancyUpdateCertainty)
  double free_update = 0.35;           // probability after one pass-through (1 - MRPT maxFreenessUpdateCertainty)
};

struct GridGeometry {
  int width = 0, height = 0;
  double resolution = 0;
  Pose2D origin;  // lower-left corner of cell (0, 0)
};

class GridMapper {
 public:
  GridMapper(const GridMapperParams& params, const Pose2D& laser_in_base);
  ~GridMapper();

  // Inserts the scan taken with base_link at `pose` in the map frame.
  void insert(const LaserScan& scan, const Pose2D& pose);
  void clear();
  // Frees the cells and leaves an empty map of one cell, version unchanged: for a grid whose
  // cells were exported and will not change unless drawn again from clear() on.
  void release();

  GridGeometry geometry() const;
  // Writes width * height cells (row 0 at the bottom) into `cells`: -1 unknown, 0..100.
  void exportCells(int8_t* cells) const;
  OccupancyGrid toGrid() const;
  // The smallest window of the grid holding every cell a ray touched: MRPT grows its grid with
  // margins, and one submap's scans leave most of it unknown (Radish logs: the known window is
  // 0.5-0.7 of the grid).
  OccupancyGrid toKnownGrid() const;
  // Bumps on every insert(): lets a publisher tell whether the map changed.
  uint64_t version() const { return version_; }

 private:
  struct Impl;
  GridMapperParams params_;
  Pose2D laser_in_base_;
  std::unique_ptr<Impl> impl_;
  uint64_t version_ = 0;
};

}  // namespace mrslam::slam
