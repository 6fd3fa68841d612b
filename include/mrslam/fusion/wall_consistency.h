// Physical consistency of a pose beyond cell-by-cell agreement: what two robots could have
// seen if B really lies where the pose puts it. Walls may lie a few cells apart (two runs
// disagree by scale and bends, see maps/halmstad_dev), so agreement has a distance tolerance;
// what neither robot can do is see through a wall. Free space seen through a wall (one map's
// free cells just behind the other's walls, on the side the other map never saw) is what an
// overlay of two buildings along one outer wall shows, however well the wall itself agrees.
// Measured on scripts/bench_merge (README, Benchmark): correct poses stay at or below 0.23
// (one run) and 0.36 (two runs of one place); pairs of different buildings have a median of 0.68.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "mrslam/fusion/cell_transform.h"

namespace mrslam::fusion {

struct WallConsistency {
  double b_on_a = 0;        // of B's walls in A's known space, the share within tolerance of A's walls
  double a_on_b = 0;        // the same for A's walls in B's known space
  double conflict = 0;      // of those walls (both directions), the share in the other map's free
                            // space farther than the tolerance from any of its walls
  double seen_through = 0;  // of one map's free cells within 3 cells of the other's walls, the
                            // share on the other's unknown side of them (the larger direction)
};

class WallConsistencyCheck {
 public:
  // Ternary images (ternary_image.h) at one resolution; tolerance in cells.
  WallConsistencyCheck(const cv::Mat& ternary_a, const cv::Mat& ternary_b, double tolerance_cells);
  // `b_in_a` takes B's cell coordinates to A's (as CellTransform everywhere in the fusion).
  WallConsistency evaluate(const CellTransform& b_in_a) const;

 private:
  // One map. Everything is looked up around the cells where the other map's points land (a
  // few hundred thousand lookups), which is far cheaper than whole-image transforms of both maps.
  struct Side {
    cv::Mat ternary;                 // CV_8U cell states
    std::vector<cv::Point2f> walls;  // wall cell centres (an even subsample)
    std::vector<cv::Point2f> free;   // free cell centres (an even subsample)
    bool wallWithin(int x, int y, const std::vector<cv::Point>& offsets) const;
  };
  struct WallCounts {
    double known = 0, near = 0, deep_free = 0;  // landed in known space; near a wall; in deep free space
  };
  Side a_, b_;
  std::vector<cv::Point> tolerance_offsets_, behind_offsets_;  // cells within each radius of (0, 0)

  static Side makeSide(const cv::Mat& ternary);
  WallCounts countWalls(const Side& from, const Side& to, const CellTransform& transform) const;
  double seenThrough(const Side& from, const Side& to, const CellTransform& transform) const;
};

}  // namespace mrslam::fusion
