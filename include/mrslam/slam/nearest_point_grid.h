// Exact nearest-point queries within a radius over a fixed 2D point set, by bucketing the
// points in square cells.
//
// ICP pairs every scan point with its nearest reference point many times per scan. MRPT's
// k-d tree answered those queries, and on the whole Freiburg 079 log building and searching
// it took about half of the run: the tracker's reference (the returns of the last 40 key
// scans) changes with every key scan, and a tree costs n log n to build. Buckets cost n to
// build, and a query near a wall looks at the nine cells around it, whose points lie side by
// side in memory.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace mrslam::slam {

class NearestPointGrid {
 public:
  // Buckets the n points (xs[i], ys[i]) in cells of about `cell` metres; the cells are made
  // larger when the points' bounding box would need more than `max_cells` of them.
  void build(const float* xs, const float* ys, size_t n, float cell, size_t max_cells = size_t{1} << 21);
  size_t size() const { return index_.size(); }
  float cellSize() const { return cell_; }

  struct Nearest {
    int64_t index = -1;  // the point's index in the arrays given to build(); -1: none within reach
    float dist_sq = 0;
  };
  // The point nearest to (x, y) among those closer than `max_dist`. Exact: a point is only left
  // out when it is provably farther than the one returned (or than `max_dist`).
  Nearest nearest(float x, float y, float max_dist) const;

 private:
  // Scans the cells of ring `r` (Chebyshev distance r from cell (cx, cy)) that lie in the grid.
  void scanRing(int cx, int cy, int r, float x, float y, Nearest& best) const;
  void scanCell(int gx, int gy, float x, float y, Nearest& best) const;

  float cell_ = 1;
  float x0_ = 0, y0_ = 0;  // the grid's lower-left corner
  int nx_ = 0, ny_ = 0;
  std::vector<uint32_t> start_;  // cell k's points are [start_[k], start_[k + 1]) below
  std::vector<float> px_, py_;   // the points, ordered by cell
  std::vector<uint32_t> index_;  // their indices in the arrays given to build()
};

}  // namespace mrslam::slam
