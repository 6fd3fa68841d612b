// A submap: the scans of a run of consecutive graph nodes, kept in the frame of its first node
// (the anchor), as
//   - an occupancy grid (the robot's map is these grids composed at the anchors' optimised
//     poses, so a loop closure moves whole submaps instead of re-casting every ray), and
//   - once finished, the points of its scans, from which loop closures are searched.
// The points stay where the tracker put the scans: over a stretch this short the tracker's
// relative poses are more precise than the optimised graph's (closures have 5 cm sigmas), and
// searching against points redrawn at the graph's poses cost accuracy (Intel 0.144 -> 0.151 m).
// The grid follows the graph: when an optimisation moves the nodes of one submap apart (a
// closure bent a stretch the tracker drew badly), the grid is drawn again from the kept scans
// (follow()); moving it whole kept the bad stretch in the map, doubled walls and all.
#pragma once

#include <memory>
#include <vector>

#include "mrslam/packed_grid.h"
#include "mrslam/slam/correlative_matcher.h"
#include "mrslam/slam/front_end.h"
#include "mrslam/slam/grid_mapper.h"
#include "mrslam/slam/laser_scan.h"

namespace mrslam::slam {

class Submap {
 public:
  // `points_resolution`: the loop closer's grid, to which the scans' points are thinned.
  Submap(int anchor_node, const GridMapperParams& grid, const Pose2D& laser_in_base, double points_resolution);

  int anchor() const { return anchor_; }
  // Adds a scan whose base_link is at `offset` from graph node `node`; the node lies at
  // `tracked` in the anchor's frame by the tracker (the points go there) and at `drawn` by the
  // optimised graph (the grid goes there).
  void insert(const LaserScan& scan, int node, const Pose2D& offset, const Pose2D& tracked, const Pose2D& drawn);
  // Draws the grid again where the nodes now lie (`node_poses`: anchor frame, one per
  // nodeList() entry), when one of its scans has moved more than `xy` m or `yaw` rad since it
  // was drawn. True when it did.
  bool follow(const std::vector<Pose2D>& node_poses, double xy, double yaw);
  // No more scans: the grid is exported once and kept packed (the mapper's cells are freed).
  void finish(double travel);
  bool finished() const { return finished_; }
  double finishedAtTravel() const { return finished_travel_; }
  int nodes() const { return static_cast<int>(nodes_.size()); }
  // A graph node whose base_link is at `pose` in the anchor's frame by the tracker.
  void addNode(int node, const Pose2D& pose) { nodes_.emplace_back(node, pose); }
  const std::vector<std::pair<int, Pose2D>>& nodeList() const { return nodes_; }
  // The node nearest to `position` (anchor frame) and its pose in the anchor's frame.
  const std::pair<int, Pose2D>& nearestNode(double x, double y) const;

  // The scans' returns in the anchor's frame, where the tracker put them.
  const Points2& points() const { return points_; }
  // Centre and radius (anchor frame, by the tracker) of a circle holding every pose a scan was
  // taken from.
  void poseCircle(double& cx, double& cy, double& radius) const;
  // The occupancy grid in the anchor's frame (the window of its known cells), exported when it
  // changed; never modified after. A finished submap's is unpacked afresh at every call.
  std::shared_ptr<const OccupancyGrid> grid() const;
  // The grid as a piece of the map whose frame lies at `anchor_pose`: packed once finished.
  MapPart part(const Pose2D& anchor_pose) const;
  uint64_t version() const { return mapper_.version(); }
  // Bytes of grid cells held: the mapper's (one a cell), the last export's and the packed ones.
  size_t gridBytes() const;

 private:
  struct Drawn {        // a scan in the grid: at `pose` in the anchor's frame, its node's pose o offset
    LaserScan scan;
    int node = 0;
    Pose2D offset;
    Pose2D pose;
  };

  int anchor_;
  // A finished submap keeps its cells only as the exported grid (the smallest window holding
  // its known cells), packed; the mapper is released and drawn again only by follow(). Keeping
  // both held every submap twice, each in MRPT's grid with its margins (MIT's infinite
  // corridor: 59 M cells against 31 M in the windows), and the windows unpacked held 90 MB of
  // Freiburg campus's 205 MB peak.
  void freeze();

  GridMapper mapper_;
  Pose2D laser_in_base_;
  double points_resolution_;
  std::vector<Drawn> scans_;
  Points2 points_;
  double min_x_ = 1e300, min_y_ = 1e300, max_x_ = -1e300, max_y_ = -1e300;
  std::vector<std::pair<int, Pose2D>> nodes_;  // (node, pose in the anchor's frame)
  bool finished_ = false;
  double finished_travel_ = 0;
  mutable std::shared_ptr<const OccupancyGrid> grid_;
  mutable uint64_t grid_version_ = ~0ull;
  std::shared_ptr<const PackedGrid> packed_;  // a finished submap's grid
};

}  // namespace mrslam::slam
