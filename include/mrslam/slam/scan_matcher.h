// Laser scan matching with point-to-point ICP (point_icp.h).
//   - PointCloudAligner: aligns points to a fixed reference cloud (used for loop closures
//     against a submap, and by the local map below);
//   - ScanToMapMatcher: scan-to-map matching against a local map holding the returns of the
//     last `keyframes` key scans in the robot's map frame; a scan becomes a key scan when the
//     robot has moved or turned enough since the last one, so the reference keeps its shape
//     while the robot stands still.
#pragma once

#include <Eigen/Core>
#include <deque>
#include <string>
#include <utility>
#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/laser_scan.h"
#include "mrslam/slam/point_icp.h"

namespace mrslam::slam {

struct ScanMatcherParams {
  int keyframes = 40;                 // key scans in the local map
  double keyframe_distance = 0.3;     // m moved before a new key scan
  double keyframe_angle = 0.26;       // rad turned before a new key scan (15 degrees)
  double max_correspondence = 0.5;    // m, ICP's initial matching distance (halved on convergence)
  double min_correspondence = 0.03;   // m, ICP's final matching distance
  int max_iterations = 60;
  // ICP pairs only every n-th scan point (a different n-th each time its pairing distance
  // shrinks); n is chosen per scan so that about this many points are paired (sparse 180-beam
  // scans keep all of them, dense 361- and 682-beam scans are paired at a fraction of the
  // cost). 0: pair every point.
  int correspondence_points = 180;
  double min_point_spacing = 0.02;    // m: returns closer than this to the last kept one are skipped
  double min_goodness = 0.3;          // share of points with a correspondence to accept a match
  double min_sigma_xy = 0.01;         // m, floor of the reported standard deviation
  double min_sigma_yaw = 0.003;       // rad, floor of the reported standard deviation
  double covariance_scale = 1.0;      // multiplies ICP's covariance (ICP is overconfident)
};

struct ScanMatch {
  bool ok = false;
  std::string reason;       // why not ok
  Pose2D pose;              // the points' frame in the reference's frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  double goodness = 0.0;    // share of points that found a correspondence
  int iterations = 0;
};

class PointCloudAligner {
 public:
  explicit PointCloudAligner(const ScanMatcherParams& params) : params_(params) {}

  void setReference(const std::vector<std::pair<float, float>>& reference);
  bool empty() const;
  // Aligns `points` (in their own frame) to the reference, starting from `guess`. With
  // `max_correspondence` > 0, pairs start at that distance instead of the configured one (a
  // guess from a correlative search is already within a few cells).
  ScanMatch align(const std::vector<std::pair<float, float>>& points, const Pose2D& guess,
                  double max_correspondence = 0) const;

 private:
  ScanMatcherParams params_;
  PointIcp icp_;
};

class ScanToMapMatcher {
 public:
  ScanToMapMatcher(const ScanMatcherParams& params, const Pose2D& laser_in_base);

  bool empty() const { return keys_.empty(); }
  // Aligns the scan to the local map, starting from `guess` (base_link in map); see
  // PointCloudAligner::align for `max_correspondence`.
  ScanMatch match(const LaserScan& scan, const Pose2D& guess, double max_correspondence = 0) const;
  // Adds the scan at `pose` as a key scan when it is far enough from the last one (or the
  // map is empty). Returns true when it was added.
  bool addIfKey(const LaserScan& scan, const Pose2D& pose);
  void clear();
  // The returns of all key scans in the map frame, and a counter that changes with them.
  std::vector<std::pair<float, float>> localPoints() const;
  // The returns of the key scans within `max_path` metres of path (key to key) from the newest
  // one, which is always included; all of them unless `max_path` > 0.
  std::vector<std::pair<float, float>> pointsWithinPath(double max_path) const;
  uint64_t version() const { return version_; }

 private:
  ScanMatcherParams params_;
  Pose2D laser_in_base_;
  std::deque<std::pair<Pose2D, std::vector<std::pair<float, float>>>> keys_;  // pose, points in map
  PointCloudAligner aligner_;
  uint64_t version_ = 0;
};

}  // namespace mrslam::slam
