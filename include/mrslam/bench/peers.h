// The peers mrslam is measured against in scripts/bench_merge, run on the same pairs:
//  - MRPT's CGridMapAligner (feature-based, modified RANSAC; libmrpt-dev);
//  - an m-explore-style estimator: AKAZE features on the grid image, ratio-test matching,
//    cv::estimateAffinePartial2D with RANSAC, accepted when the confidence
//    inliers / (8 + 0.3 * matches) reaches 1 (the rule m-explore's map_merge uses).
#pragma once

#include "mrslam/grid.h"

namespace mrslam::bench {

struct PeerResult {
  bool accepted = false;
  Pose2D pose;  // pose of B's map frame in A's map frame
  double time_ms = 0;
};

PeerResult alignWithMrpt(const OccupancyGrid& a, const OccupancyGrid& b);
PeerResult alignWithAkaze(const OccupancyGrid& a, const OccupancyGrid& b);

}  // namespace mrslam::bench
