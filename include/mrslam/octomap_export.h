// Export of an occupancy grid as an OctoMap (octomap::OcTree, binary .bt): every known cell
// becomes a column of voxels from the floor to `height` metres, occupied or free as in the
// grid, so 3D tools (octovis, MoveIt, OctoMap servers) can use the 2D map.
#pragma once

#include <string>

#include "mrslam/grid.h"

namespace mrslam {

// Writes the file whole or not at all (atomic_file.h); throws std::runtime_error naming the
// file when it cannot be written. Returns the number of leaf voxels written.
size_t saveOctomap(const OccupancyGrid& grid, const std::string& path, double height = 0.5,
                   int occupied_threshold = 65, int free_threshold = 25);

}  // namespace mrslam
