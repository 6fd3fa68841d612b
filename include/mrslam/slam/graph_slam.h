// One robot's SLAM with a pose graph (the default front end).
//
// The paper's cascaded EKF stays the local tracker; its poses are the odometry of a graph whose
// nodes are key scans (every node_distance / node_angle). Consecutive nodes are joined by the
// tracker's motion, weak (weak_edge_factor) where a scan was matched poorly: into and out of a
// node whose own scan was, with the motion across that node kept at full weight. Every new node
// is searched against older finished submaps (loop_closer.h), and every submap when it is
// finished against the older nodes among its poses (as Cartographer matches nodes and submaps
// both ways: a stretch the tracker drew badly before the robot came back is only found from the
// return's submap); each closure found becomes an edge with a robust loss. The graph is
// optimised (Ceres by default) whenever closures are added; a closure whose error at the
// optimum exceeds loop_outlier_chi2 is dropped and the graph optimised again, so one wrong
// closure cannot wreck the map. A closure that would move the graph further than
// loop_confirm_xy / _yaw from what it believes is held until a second closure agrees with it
// (pairwise consistency through the tracker's motion between the two nodes, the second from a
// node at least loop_consistency_min_travel further along) and dropped if none does within
// loop_confirm_travel.
// A failed optimisation keeps the last good poses and says why (stats().last_problem).
//
// The map: scans go into submaps (submap.h) in their anchor node's frame; the map is the
// submaps composed at their anchors' optimised poses, so a correction moves submaps rather than
// re-casting every ray. A submap whose own nodes an optimisation moved apart by more than
// graph_redraw_xy / _yaw is drawn again from its scans, so a stretch a closure straightened is
// straight in the map too (loop closures still search the points where the tracker put them,
// submap.h). The pose of the robot and of every scan follow the optimised nodes.
#pragma once

#include <memory>
#include <vector>

#include "mrslam/slam/front_end.h"
#include "mrslam/slam/local_tracker.h"
#include "mrslam/slam/loop_closer.h"
#include "mrslam/slam/pose_graph.h"
#include "mrslam/slam/submap.h"

namespace mrslam::slam {

class GraphSlam : public FrontEnd {
 public:
  GraphSlam(const RobotSlamParams& params, const Pose2D& laser_in_base);

  void addOdometry(const Pose2D& increment) override { tracker_.addOdometry(increment); }
  void addGyro(double yaw_increment, double variance) override { tracker_.addGyro(yaw_increment, variance); }
  ScanStep processScan(const LaserScan& scan) override;
  void reset() override;
  void setTimeUsable(bool usable) override { tracker_.setTimeUsable(usable); }
  void setOdometryAvailable(bool available) override { tracker_.setOdometryAvailable(available); }
  void finish() override;

  Pose2D pose() const override;
  Eigen::Matrix3d covariance() const override { return tracker_.filter().covariance(); }
  std::vector<Pose2D> trajectory() const override;
  std::vector<MapPart> mapParts() const override;
  uint64_t mapVersion() const override { return map_version_; }
  FrontEndStats stats() const override { return stats_; }
  std::string name() const override { return "graph"; }

  // For tests and tools: the graph as it stands.
  const std::vector<Pose2D>& nodePoses() const { return poses_; }
  const std::vector<PoseGraphEdge>& edges() const { return edges_; }
  // Bytes of loop-closure search grids held now (loop_matcher_cache_mb bounds them).
  size_t loopSearchBytes() const { return closer_.cachedBytes(); }
  // Adds a loop-closure edge as if the search had found it, and optimises (tests inject
  // false closures this way).
  void addLoopClosure(int from_node, int to_node, const Pose2D& measurement);

 private:
  struct Node {
    Pose2D tracker_pose;  // in the tracker's frame
    double travel = 0;    // m along the trajectory
    Points2 points;       // returns in base_link, thinned
    bool weak_before = false;  // a scan between the previous node and this one was matched weakly
    bool own_weak = false;     // this node's own scan was: its pose alone may be off
    // A scan since the previous node, this one's included, was matched weakly.
    bool weak() const { return weak_before || own_weak; }
  };
  struct Closure {         // a loop closure: node `to` at `measurement` in the frame of `from`
    int from = 0, to = 0;
    Pose2D measurement;
    double travel = 0;       // of node `to`: closures from nodes this far apart are independent views
    double found_at = 0;     // travel when it was found (a pending closure expires after loop_confirm_travel)
    bool lone = false;       // node `to` was lone (loneNodes) when it was found
  };
  struct ScanRef {        // a scan's pose is poses_[node] o offset
    int node = 0;
    Pose2D offset;
  };

  bool isNewNode(const Pose2D& tracker_pose) const;
  // `weak_before`: a scan between the last node and this one was matched weakly; `own_weak`:
  // this one was.
  void addNode(const LaserScan& scan, const Pose2D& tracker_pose, bool weak_before, bool own_weak, ScanStep& step);
  // The tracker's motion from the previous node to `node`, and around the previous node when
  // its own scan alone was matched weakly.
  void addTrackerEdges(int node);
  // Whether the tracker's motion from node `to` - 1 to `to` is weak: a scan matched weakly
  // since that node, or that node's own scan, whose pose the motion starts from.
  bool weakEdge(int to) const;
  Submap& activeSubmap();
  // Where node `node` lies in the frame of the submap's anchor, by the tracker and by the
  // optimised graph.
  Pose2D trackedInAnchor(const Submap& submap, int node) const;
  Pose2D optimizedInAnchor(const Submap& submap, int node) const;
  // Draws the grid of every submap whose nodes the last optimisation moved apart again (submap.h).
  void followOptimizedPoses();
  void closeLoops(int node, ScanStep& step);
  // Older nodes against the submap just finished: a node the tracker placed badly before the
  // robot came back (the start of a run, a lost stretch) is tied to what the return drew.
  void closeLoopsOfOlderNodes(int submap, ScanStep& step);
  // Admits the closures found (node `to` against the submap's node nearest the match) and
  // optimises when one disagrees with the graph.
  void addClosures(const std::vector<std::pair<int, LoopClosure>>& found, ScanStep& step);
  // The closures to add now: `c` itself when it agrees with the graph, `c` and an earlier
  // pending closure when the two agree with each other, else none (`c` waits).
  std::vector<Closure> admit(const Closure& c);
  bool agreesWithGraph(const Closure& c) const;
  bool consistent(const Closure& a, const Closure& b) const;
  // How much further than loop_consistency_xy / _yaw the tracker's motion between nodes a and
  // b may be off (m, rad): loop_consistency_weak_sigmas of the weak edges on that stretch, at
  // most the lone window.
  std::pair<double, double> weakMotionSlack(int a, int b) const;
  void expirePending();
  double loopLength() const;  // a closure's length in graphDistances
  // Per node: next to a stretch the tracker matched weakly (Node::weak()) and tied to the map by
  // no closure yet. Such a node may lie further off than any window grown with the graph
  // distance (the start of a run before the tracker matched anything: Intel every 5th, 44
  // degrees), so the reverse search looks for it in the loop_lone_window.
  std::vector<char> loneNodes() const;
  PoseGraphEdge odometryEdge(int from, int to, bool weak) const;
  PoseGraphEdge loopEdge(int from, int to, const Pose2D& measurement) const;
  // Optimises; drops closures the optimum disagrees with. True when the poses moved.
  bool optimize();
  // Every node's points (Node::points), in node order: what the end-of-run steps align.
  std::vector<const Points2*> nodeScans() const;
  // When the run ends: a stretch turned against the rest by a turn the odometry may have missed
  // (doubted_splits_) put back, if the scans clearly say where (stretch_reanchor.h).
  void reanchorStretches();
  // When the run ends: each node's scan aligned to all the others' (pose_refinement.h).
  void refineNodes();

  RobotSlamParams params_;
  LocalTracker tracker_;
  LoopCloser closer_;
  std::unique_ptr<PoseGraphSolver> solver_;
  std::vector<Node> nodes_;
  std::vector<Pose2D> poses_;  // optimised node poses in the map frame
  std::vector<PoseGraphEdge> edges_;
  std::vector<std::unique_ptr<Submap>> submaps_;
  std::vector<ScanRef> scans_;
  std::vector<Closure> pending_;  // closures waiting for a consistent partner
  std::vector<int> doubted_splits_;  // first nodes after steps whose turn the scans doubted
  double travel_ = 0;
  bool weak_since_node_ = false;  // a scan since the last node was matched poorly or not at all
  int unoptimized_closures_ = 0, nodes_since_optimization_ = 0;
  Pose2D last_tracker_pose_;
  uint64_t map_version_ = 0;
  FrontEndStats stats_;
};

}  // namespace mrslam::slam
