// Trajectory accuracy in the spirit of Kümmerle et al. 2009 ("On measuring the accuracy of
// SLAM algorithms"): errors of relative motions between pairs of scans, which do not depend
// on the frame either trajectory is expressed in.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "mrslam/grid.h"

namespace mrslam::bench {

struct RelationError {
  double trans_mean = 0, trans_std = 0;  // m
  double rot_mean = 0, rot_std = 0;      // rad
  size_t count = 0;
};

// A relation: the motion from pose i to pose j (pose j in the frame of pose i).
struct Relation {
  size_t i = 0, j = 0;
  Pose2D motion;
};

// Error of every relation: |(est_i^-1 est_j) ⊖ motion|, translation and angle. Relations with
// an end outside `estimate` are skipped.
RelationError relationError(const std::vector<Pose2D>& estimate, const std::vector<Relation>& relations);
// The same with each relation (i, j) taken from `reference`.
RelationError relationError(const std::vector<Pose2D>& estimate, const std::vector<Pose2D>& reference,
                            const std::vector<std::pair<size_t, size_t>>& pairs);

// (i, i + step) for every i.
std::vector<std::pair<size_t, size_t>> consecutivePairs(size_t n, size_t step);
// `count` pairs of distinct scans drawn with a fixed seed.
std::vector<std::pair<size_t, size_t>> randomPairs(size_t n, size_t count, unsigned seed);

// The rigid transform T minimising sum |T * from_i - to_i|^2 over the positions (2D Umeyama,
// no scale): where a trajectory's frame sits in the reference's frame. Needs >= 2 poses.
Pose2D fitRigid(const std::vector<Pose2D>& from, const std::vector<Pose2D>& to);

// Where a global error comes from: the estimate is placed in the reference's frame (fitRigid
// on the positions; its headings turned by the same angle), then scored over `pairs` twice,
// once with the reference's positions and its own headings, once with its own positions and
// the reference's headings. A heading off by 1 degree at pose i moves every relation out of i
// by 1.7 cm per metre to j, so on a large map the headings alone can make most of the error.
struct GlobalErrorSplit {
  double own_headings = 0;   // m: reference positions, the estimate's headings
  double own_positions = 0;  // m: the estimate's positions, reference headings
};
GlobalErrorSplit splitGlobalError(const std::vector<Pose2D>& estimate, const std::vector<Pose2D>& reference,
                                  const std::vector<std::pair<size_t, size_t>>& pairs);

// Reads "timestamp x y yaw [scan]" lines (scan: the index of the scan in its log, written by
// mrslam_slam_log; -1 where absent); throws std::runtime_error naming the line on bad input.
struct TrajectoryEntry {
  double stamp = 0;
  Pose2D pose;
  long scan = -1;
};
std::vector<TrajectoryEntry> readIndexedTrajectory(const std::string& path);
// The same as (stamp, pose) pairs.
std::vector<std::pair<double, Pose2D>> readTrajectory(const std::string& path);

}  // namespace mrslam::bench
