// A submap: the scans of a run of consecutive graph nodes, kept in the frame of its first node
// (the anchor) with the tracker's relative poses, as
//   - an occupancy grid (the robot's map is these grids composed at the anchors' optimised
//     poses, so a loop closure moves whole submaps instead of re-casting every ray), and
//   - once finished, the points of its scans, from which loop closures are searched.
#pragma once

#include <memory>

#include "mrslam/slam/correlative_matcher.h"
#include "mrslam/slam/grid_mapper.h"
#include "mrslam/slam/laser_scan.h"

namespace mrslam::slam {

class Submap {
 public:
  Submap(int anchor_node, const GridMapperParams& grid, const Pose2D& laser_in_base);

  int anchor() const { return anchor_; }
  // Adds a scan whose base_link is at `pose` in the anchor's frame; `points` are its returns
  // in base_link, thinned.
  void insert(const LaserScan& scan, const Points2& points, const Pose2D& pose);
  // No more scans: the grid is exported once and kept.
  void finish(double travel);
  bool finished() const { return finished_; }
  double finishedAtTravel() const { return finished_travel_; }
  int nodes() const { return static_cast<int>(nodes_.size()); }
  // A graph node whose base_link is at `pose` in the anchor's frame.
  void addNode(int node, const Pose2D& pose) { nodes_.emplace_back(node, pose); }
  const std::vector<std::pair<int, Pose2D>>& nodeList() const { return nodes_; }
  // The node nearest to `position` (anchor frame) and its pose in the anchor's frame.
  const std::pair<int, Pose2D>& nearestNode(double x, double y) const;

  // The scans' returns in the anchor's frame.
  const Points2& points() const { return points_; }
  // Centre and radius (anchor frame) of a circle holding every pose a scan was taken from.
  void poseCircle(double& cx, double& cy, double& radius) const;
  // The occupancy grid in the anchor's frame, exported when it changed; never modified after.
  std::shared_ptr<const OccupancyGrid> grid() const;
  uint64_t version() const { return mapper_.version(); }

 private:
  int anchor_;
  GridMapper mapper_;
  Points2 points_;
  double min_x_ = 1e300, min_y_ = 1e300, max_x_ = -1e300, max_y_ = -1e300;
  std::vector<std::pair<int, Pose2D>> nodes_;  // (node, pose in the anchor's frame)
  bool finished_ = false;
  double finished_travel_ = 0;
  mutable std::shared_ptr<const OccupancyGrid> grid_;
  mutable uint64_t grid_version_ = ~0ull;
};

}  // namespace mrslam::slam
