// Free space seen through a wall: neither robot can see through one, so if B really lies where
// a pose puts it, B's free space cannot lie just behind A's walls on the side A never saw (nor
// A's behind B's). An overlay of two buildings along one outer wall agrees on that wall cell
// for cell and passes every other check; this is what gives it away. Measured on
// scripts/bench_merge (README, Benchmark): correct poses stay at or below 0.23 (one run) and
// 0.36 (two runs of one place); pairs of different buildings have a median of 0.68.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "mrslam/fusion/cell_transform.h"

namespace mrslam::fusion {

class SeeThroughCheck {
 public:
  // Ternary images (ternary_image.h) at one resolution.
  SeeThroughCheck(const cv::Mat& ternary_a, const cv::Mat& ternary_b);
  // Of one map's free cells within 3 cells of the other's walls, the share on the other's
  // unknown side of them; the larger of the two directions. `b_in_a` takes B's cell
  // coordinates to A's (as CellTransform everywhere in the fusion).
  double seenThrough(const CellTransform& b_in_a) const;

 private:
  // One map. Everything is looked up around the cells where the other map's free cells land,
  // which is far cheaper than whole-image transforms of both maps.
  struct Side {
    cv::Mat ternary;                // CV_8U cell states
    std::vector<cv::Point2f> free;  // free cell centres (an even subsample)
    bool wallNear(int x, int y) const;
  };
  Side a_, b_;

  static Side makeSide(const cv::Mat& ternary);
  static double behindWalls(const Side& from, const Side& to, const CellTransform& transform);
};

}  // namespace mrslam::fusion
