// The loop-closure search (ours to own): a new graph node against older, finished submaps.
//
// For each submap near the node's predicted pose (nearest first, those finished at least
// loop_min_travel back along the trajectory), a correlative search over a window that grows
// with the distance travelled since the last closure; a match must score loop_min_score, must
// beat every rival pose elsewhere in the window clearly (loop_max_rival: corridors and
// repeated rooms give several good poses), and must survive ICP refinement against the
// submap's points. What passes becomes a loop-closure edge; the graph may still drop it when
// the optimum disagrees (graph_slam.h).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "mrslam/slam/correlative_matcher.h"
#include "mrslam/slam/front_end.h"
#include "mrslam/slam/scan_matcher.h"
#include "mrslam/slam/submap.h"

namespace mrslam::slam {

struct LoopClosure {
  int submap = 0;       // index of the submap matched
  Pose2D pose;          // the node's pose in the submap's anchor frame
  double score = 0;     // correlative score of the refined pose
  double rival = 0;     // best score elsewhere in the window (0: none above the floor)
};

// Where to search: the node's pose and the submaps' anchor poses in the map frame, how far the
// robot travelled, and how far each node is from this one through the graph (pose_graph.h:
// graphDistances), which sizes the window for each submap.
struct LoopQuery {
  Points2 points;        // the node's returns in base_link, thinned
  Pose2D pose;           // predicted pose of the node in the map frame
  double travel = 0;
  std::vector<double> graph_distance;  // per node, m
};

class LoopCloser {
 public:
  LoopCloser(const GraphParams& params, const ScanMatcherParams& icp);

  // Closures for the node (at most loop_max_candidates submaps are tried); counts attempts and
  // rejections into `stats`.
  std::vector<LoopClosure> search(const LoopQuery& query, const std::vector<std::unique_ptr<Submap>>& submaps,
                                  const std::vector<Pose2D>& anchor_poses, FrontEndStats& stats);
  // A node (its thinned `points` in base_link, predicted at `pose` in the map) against one
  // submap within `window` (xy m, yaw rad; window(distance) for a node `distance` m away
  // through the graph), as search() tries each candidate; the reverse search (older nodes
  // against a newly finished submap) uses it alone.
  std::optional<LoopClosure> tryClosure(const Points2& points, const Pose2D& pose, int index, const Submap& submap,
                                        const Pose2D& anchor_pose, std::pair<double, double> window,
                                        FrontEndStats& stats);
  // How far a node at `pose` is beyond the submap's pose circle (m; negative inside it).
  double beyond(const Submap& submap, const Pose2D& anchor_pose, const Pose2D& pose) const;
  void clear() {
    cache_.clear();
    given_up_.clear();
  }
  // Drops the submap's matchers (built again when next needed).
  void forget(int index) { cache_.erase(index); }
  // Drops every cached matcher (built again when next needed); the search decides the same.
  void releaseCache() { cache_.clear(); }
  // Bytes the cached matchers' grids hold now (at most loop_matcher_cache_mb, unless one
  // submap's alone is larger).
  size_t cachedBytes() const;
  // The search window for poses `distance` m apart through the graph: (xy m, yaw rad).
  std::pair<double, double> window(double distance) const;
  // The graph distance beyond which the window no longer grows.
  double saturationDistance() const;

 private:
  struct Matchers {  // built once per submap, kept for the most recently used
    std::unique_ptr<CorrelativeMatcher> correlative;
    std::unique_ptr<PointCloudAligner> icp;
    uint64_t used = 0;
  };
  const Matchers& matchersOf(int index, const Submap& submap);
  // Drops the least recently used matchers until `bytes` more fit loop_matcher_cache_mb.
  void makeRoomFor(size_t bytes);

  GraphParams params_;
  ScanMatcherParams icp_params_;
  std::map<int, Matchers> cache_;
  std::map<int, int> given_up_;  // searches of each submap that gave up (kMaxEvaluations)
  uint64_t clock_ = 0;
};

}  // namespace mrslam::slam
