// An occupancy grid kept packed (Zstandard): its geometry, and its cells only as a compressed
// stream, unpacked while something reads them. A finished submap's grid is read only when the
// map is composed, and its known window is two-thirds unknown and long runs of free: packed it
// takes an eighth of the bytes (Freiburg campus's submaps: 92 MB of cells in 11.5 MB).
#pragma once

#include <cstdint>
#include <vector>

#include "mrslam/grid.h"

namespace mrslam {

class PackedGrid {
 public:
  explicit PackedGrid(const OccupancyGrid& grid);

  // Width, height, resolution and origin; no cells.
  const OccupancyGrid& geometry() const { return geometry_; }
  // The grid as it was packed.
  OccupancyGrid unpack() const;
  // Bytes of the packed cells.
  size_t bytes() const { return cells_.size(); }

 private:
  OccupancyGrid geometry_;
  std::vector<uint8_t> cells_;
};

}  // namespace mrslam
