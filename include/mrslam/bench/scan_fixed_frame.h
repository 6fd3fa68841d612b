// A second truth for the pose of one robot's map frame in another's, fixed by the scans where
// the two robots saw the same place, not by the log's reference poses between them.
//
// peer_frame_truth.h places each robot's map frame in the world by fitting its whole path to the
// reference poses. That truth averages each robot's own drift over its window, and it inherits
// the reference's own noise: on robot3's window of the multi-robot rostest (Intel 1864-2000 s)
// the reference's steps differ from what scan-to-scan ICP fixes by 3.7 cm RMS, ours by 2.1 cm,
// so at one cell (5 cm) it cannot say whether a merge is right.
//
// Here each pair of scans, one from each robot, that the reference puts within a few metres of
// each other is aligned by the independent point-to-line ICP of scan_relations.h, with all its
// checks (five seeds agree, the reverse match agrees, enough inliers, no free direction): not
// scan to scan but local map to local map, each scan drawn with its robot's scans within
// local_path of it along its path at that robot's own poses (two robots rarely scan a place
// from near one pose: of the rostest's windows' 77-277 candidate pairs per robot pair, 11-93
// became relations scan to scan, 55-214 so). A relation k between robot N's scan i and robot M's scan j, composed with the robots'
// own poses of those scans, says where M's map frame lies in N's:
//     T_k = E_N(i) * relation_k * E_M(j)^-1.
// Its heading is the median of the T_k's, its position the median, per axis, of where the T_k's
// put the measuring point (the centre of M's path, as peerFrameError measures). The spread of the
// T_k's about it is this truth's own error: each robot's map is bent a little between the places
// the relations tie, and a merge can only be as right as the maps agree with each other.
#pragma once

#include <cstddef>
#include <optional>

#include "mrslam/bench/peer_frame_truth.h"
#include "mrslam/bench/scan_relations.h"
#include "mrslam/slam/robot_log.h"

namespace mrslam::bench {

struct ScanFixedParams {
  size_t min_relations = 5;   // fewer relations give no truth
  size_t max_tried = 100;     // scan pairs aligned at most (a seeded sample when there are more)
  unsigned seed = 1;
  double local_path = 1.5;    // m of each robot's path either side of a scan drawn with it (0: the scan
                              // alone): 1.5 or 3 m left the truths' spread over their relations at
                              // 0.1-1.3 cells on the rostest's windows, the scans alone 0.3-1.3
  // Two robots pass a place in different directions and rarely within the 2 m / 46 degrees that
  // pair the passes of one robot (scan_relations.h): on the multi-robot rostest's windows those
  // leave no relation between robot1 and robot3, 3 m / 86 degrees leave 12. The checks still
  // decide which pairs become relations.
  ScanRelationParams relation = [] {
    ScanRelationParams p;
    p.max_distance = 3.0, p.max_turn = 1.5;
    return p;
  }();
};

struct ScanFixedFrame {
  Pose2D truth;            // M's map frame in N's
  size_t relations = 0;    // scan pairs the checks kept
  size_t tried = 0;        // scan pairs aligned
  double spread_m = 0;     // RMS distance of the T_k's measuring points from the truth's
  double spread_deg = 0;   // RMS heading difference of the T_k's from the truth's
};

// The truth above, M's map frame in N's; nothing when too few relations pass the checks. Each
// track's scans are found in the log by their reference poses (a bag restamps a window's
// scans); the reference only picks the candidate pairs and seeds their ICP.
std::optional<ScanFixedFrame> scanFixedPeerFrame(const slam::RobotLog& log, const RobotTrack& n, const RobotTrack& m,
                                                 const ScanFixedParams& params = {});

}  // namespace mrslam::bench
