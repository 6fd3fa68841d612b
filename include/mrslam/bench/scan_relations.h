// Relations checked against the scans: an accuracy yardstick that does not take the reference
// poses' word for it.
//
// A corrected log's reference poses are themselves the output of a SLAM run and carry errors of
// their own. Kümmerle et al. (2009) built their benchmark relations by matching pairs of scans
// and checking every match by hand; this builds relations from a log the same way, checked by a
// rule instead of a person. Scan pairs from different passes over one place (the reference says
// which, within a metre) are aligned by point-to-line ICP from the reference's relative pose and
// from four seeds around it, and a pair becomes a relation only when all five runs end at one
// pose with enough of the second scan's points on the first scan's walls, and matching the
// first scan onto the second finds the same pose. The ICP is written here,
// not the MRPT point-to-point ICP that mrslam's tracker uses, so the yardstick is not the
// tracker's own matcher.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "mrslam/bench/trajectory_metrics.h"
#include "mrslam/slam/robot_log.h"

namespace mrslam::bench {

struct ScanRelationParams {
  double max_distance = 2.0;        // m between the two scans' reference positions...
  double max_turn = 0.8;            // rad: ...and at most this between their headings...
  double min_path = 10.0;           // m: ...with at least this much reference path between them
                                    // (another pass over the place, not the next scans)
  double seed_offset_xy = 0.3;      // m: the four extra seeds sit this far from the reference's
  double seed_offset_yaw = 0.087;   // rad  relative pose (5 degrees), each in another direction
  double agree_xy = 0.01;           // m: every seed's result within this...
  double agree_yaw = 0.0017;        // rad: ...and this (0.1 degree) of the reference seed's
  double reverse_agree_xy = 0.02;   // m: the first scan matched onto the second ends this close to
  double reverse_agree_yaw = 0.0035;// rad  the same relation (0.2 degree; other points, other walls)
  double inlier_distance = 0.05;    // m from the first scan's walls...
  double min_inlier_share = 0.3;    // ...for at least this share of the second scan's points
  double max_range = 20.0;          // m: longer returns are left out
  double min_constraint = 0.1;      // walls across the weakest direction: the smallest eigenvalue
                                    // of the pairs' normals' spread (sum of n n^T per pair, 0..0.5);
                                    // below it the match can slide (a corridor) and is no relation
};

// The relations kept, and how many candidate pairs there were and were tried.
struct ScanRelations {
  std::vector<Relation> relations;  // motion: robot pose at scan j in the robot frame at scan i
  size_t candidates = 0, tried = 0;
};

// Up to `count` relations between scans of `log` (which must have reference poses), candidates
// drawn in a seeded order (from a seeded sample of 200000 where there are more).
ScanRelations scanCheckedRelations(const slam::RobotLog& log, size_t count, unsigned seed,
                                   const ScanRelationParams& params = {});

// The relation between scans i and j of `log` when the scans fix it (the checks above), seeded
// with the reference's relative pose.
std::optional<Relation> scanCheckedRelation(const slam::RobotLog& log, size_t i, size_t j, const ScanRelationParams& params = {});

// The same checks between two local maps: the scans of `log` listed in scans_a (record index,
// pose in a's frame) against those in scans_b: the pose of b's frame in a's, when the two fix
// it, starting from `guess`. Two robots rarely scan one place from near the same pose; the few
// scans around each see more of the walls both saw.
std::optional<Pose2D> localMapRelation(const slam::RobotLog& log, const std::vector<std::pair<size_t, Pose2D>>& scans_a,
                                       const std::vector<std::pair<size_t, Pose2D>>& scans_b, const Pose2D& guess,
                                       const ScanRelationParams& params = {});

// Point-to-line ICP of scan `b` onto scan `a` (both with the laser at `laser_in_base`): the robot
// pose at b in the robot frame at a, starting from `seed`; nothing when too few points pair up
// or the pairs leave a direction free (min_constraint).
// `inlier_share` receives the share of b's points within `inlier_distance` of a's walls.
std::optional<Pose2D> alignScans(const slam::LaserScan& a, const slam::LaserScan& b, const Pose2D& laser_in_base,
                                 const Pose2D& seed, const ScanRelationParams& params = {},
                                 double* inlier_share = nullptr);

}  // namespace mrslam::bench
