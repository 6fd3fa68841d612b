// The grid a CompressedMapShare carries, inflated with every check the map-merge nodelet makes
// (shared with the fuzz target). Needs the generated message, so kept out of ros_conversions.h,
// which the offline tools include.
#pragma once

#include <mrslam/CompressedMapShare.h>
#include <nav_msgs/OccupancyGrid.h>

#include <string>

#include "mrslam/cell_codec.h"
#include "ros_conversions.h"

namespace mrslam::nodelets {

// The grid a CompressedMapShare carries, into `grid` (header, info, cells); empty when it can be
// used, else why not. The cells are inflated only when the geometry is usable, to exactly
// width x height of them.
inline std::string inflateGrid(const CompressedMapShare& msg, int64_t max_cells, nav_msgs::OccupancyGrid& grid) {
  grid.header = msg.map_header;
  grid.info = msg.info;
  grid.data.clear();
  const std::string problem = gridInfoProblem(msg.info, max_cells);
  if (!problem.empty()) return problem;
  if (msg.encoding != "zlib") return "unknown encoding '" + printable(msg.encoding) + "'";
  return decompressCells(msg.cells.data(), msg.cells.size(), static_cast<size_t>(msg.info.width) * msg.info.height,
                         grid.data);
}

}  // namespace mrslam::nodelets
