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
  // The same, leaving out the points given to build() at indices [skip_first, skip_last): a
  // scan's own points, where the reference holds every scan (pose_refinement.h).
  Nearest nearestExcept(float x, float y, float max_dist, size_t skip_first, size_t skip_last) const;

 private:
  // A point of the given index may be the answer: every one, or every one outside a range. A
  // template parameter, so that the tracker's queries (most of a run's time) test nothing.
  struct Any {
    bool operator()(uint32_t) const { return true; }
  };
  struct Outside {
    uint32_t first, count;
    bool operator()(uint32_t index) const { return index - first >= count; }  // unsigned: below first wraps
  };
  template <typename Accept>
  Nearest nearestIf(float x, float y, float max_dist, Accept accept) const;
  // Scans the cells of ring `r` (Chebyshev distance r from cell (cx, cy)) that lie in the grid.
  template <typename Accept>
  void scanRing(int cx, int cy, int r, float x, float y, Accept accept, Nearest& best) const;
  template <typename Accept>
  void scanCell(int gx, int gy, float x, float y, Accept accept, Nearest& best) const;

  float cell_ = 1;
  float x0_ = 0, y0_ = 0;  // the grid's lower-left corner
  int nx_ = 0, ny_ = 0;
  std::vector<uint32_t> start_;  // cell k's points are [start_[k], start_[k + 1]) below
  std::vector<float> px_, py_;   // the points, ordered by cell
  std::vector<uint32_t> index_;  // their indices in the arrays given to build()
};

}  // namespace mrslam::slam
