// Pairs of real maps of one place from separate mapping runs (maps/halmstad_dev, README
// there), with the truth the data set's annotations give: the least-squares rigid transform
// (Kabsch) taking B's annotated corners onto A's. No rigid pose makes two runs agree cell for
// cell (1-5 % scale, bends, moved furniture), so "correct" is judged on the corners, with the
// tolerance the README defines: |yaw error| <= 2 deg and B's corners, moved by the estimate,
// within max(10 cells, 2 x the truth's own median residual) of where the truth moves them
// (median over the corners).
#pragma once

#include <string>
#include <vector>

#include "mrslam/grid.h"

namespace mrslam::bench {

struct MultiRunPair {
  std::string map_a, map_b;           // run names, e.g. E5_01
  std::vector<double> ax, ay, bx, by; // annotated corners, metres in each map's frame
  Pose2D truth;                       // pose of B's map frame in A's (Kabsch on the corners)
  double truth_residual_cells = 0;    // median distance of the truth's moved corners to A's
};

// The place's run maps are PNGs: 0 occupied, 127 unknown, 255 free; `resolution` m per cell,
// origin at the lower-left corner. Throws std::runtime_error naming the file on failure.
OccupancyGrid loadRunMap(const std::string& png_path, double resolution);

// Every ordered pair of correspondences.csv in `dir`, with its truth. Throws
// std::runtime_error naming the file and line on a malformed row.
std::vector<MultiRunPair> readMultiRunPairs(const std::string& dir, double resolution);

struct MultiRunJudgement {
  double yaw_err_deg = 0;
  double corner_err_cells = 0;  // median over the corners
  double tolerance_cells = 0;
  bool correct = false;         // the README's rule (does not look at whether it was accepted)
};
MultiRunJudgement judgeMultiRun(const MultiRunPair& pair, const Pose2D& estimate, double resolution);

}  // namespace mrslam::bench
