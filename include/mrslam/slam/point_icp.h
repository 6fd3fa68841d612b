// Point-to-point ICP in the plane: each scan point is paired with its nearest reference point
// within a pairing distance, the rigid pose that best fits the pairs is solved in closed form,
// and the two steps repeat. The pairing distance halves each time the pose stops moving, down
// to a final distance (the schedule of MRPT's classic CICP, which the tracker used before).
//
// Ours rather than MRPT's CICP because of what linking it cost: libmrpt-slam brings 116 more
// shared libraries (its vision module and OpenCV's), 32 MB resident in every process that
// tracks a scan, whether it reads a camera or not. The pairs were already ours
// (nearest_point_grid.h); the loop, the fit and the covariance are a few dozen lines.
// test_point_icp.cpp holds it to MRPT's CICP on real scans.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/nearest_point_grid.h"

namespace mrslam::slam {

struct IcpSchedule {
  double max_correspondence = 0.5;   // m, first pairing distance
  double min_correspondence = 0.03;  // m, the run ends once the distance would fall below this (> 0)
  int max_iterations = 60;           // then the distance shrinks every iteration until it ends
  // Only every n-th scan point is paired (n = decimation); the first one paired moves on by one
  // each time the distance shrinks, so that every point takes part over the run.
  size_t decimation = 1;
};

struct IcpResult {
  Pose2D pose;                // the points' frame in the reference's frame
  // From how sharply the pairs' (robustified) squared distances rise as the pose moves; not
  // scaled by any noise level (the caller scales it).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  double goodness = 0;        // share of the points paired at the last pairing distance
  int iterations = 0;
  bool paired = false;        // false: not a single pair was found
};

// Reference points, by their index in what setReference() was given, that are never paired:
// [first, last), none by default. A reference holding every scan of a map leaves out the scan
// being aligned (pose_refinement.h).
struct SkipRange {
  size_t first = 0, last = 0;
};

class PointIcp {
 public:
  void setReference(const std::vector<std::pair<float, float>>& points);
  bool empty() const { return xs_.empty(); }
  IcpResult align(const std::vector<std::pair<float, float>>& points, const Pose2D& guess,
                  const IcpSchedule& schedule, SkipRange skip = {}) const;

 private:
  struct Pair {
    float ref_x, ref_y;  // the reference point
    float x, y;          // the scan point, in the scan's frame
  };
  // The pairs of every `decimation`-th scan point from `offset` on, the points moved by `pose`,
  // never with a reference point in `skip` (here in xs_'s indices). None when the moved points'
  // bounding box misses the reference's.
  std::vector<Pair> pairs(const std::vector<std::pair<float, float>>& points, const Pose2D& pose, double reach,
                          size_t decimation, size_t offset, SkipRange skip) const;

  NearestPointGrid grid_;
  std::vector<float> xs_, ys_;
  std::vector<uint32_t> source_;  // each of xs_'s index in setReference's input (non-finite ones left out)
  float x_min_ = 0, x_max_ = 0, y_min_ = 0, y_max_ = 0;
};

}  // namespace mrslam::slam
