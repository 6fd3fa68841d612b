#include "mrslam/octomap_export.h"

#include <octomap/OcTree.h>

#include <stdexcept>

#include "mrslam/atomic_file.h"

namespace mrslam {

size_t saveOctomap(const OccupancyGrid& grid, const std::string& path, double height, int occupied_threshold,
                   int free_threshold) {
  const std::string problem = validateGrid(grid);
  if (!problem.empty()) throw std::runtime_error(path + ": cannot export: " + problem);
  octomap::OcTree tree(grid.resolution);
  const double c = std::cos(grid.origin.yaw), s = std::sin(grid.origin.yaw);
  const int layers = std::max(1, static_cast<int>(std::lround(height / grid.resolution)));
  for (int row = 0; row < grid.height; ++row)
    for (int col = 0; col < grid.width; ++col) {
      const int v = grid.at(col, row);
      if (v < 0 || (v > free_threshold && v < occupied_threshold)) continue;
      const double lx = (col + 0.5) * grid.resolution, ly = (row + 0.5) * grid.resolution;
      const double x = grid.origin.x + c * lx - s * ly, y = grid.origin.y + s * lx + c * ly;
      for (int k = 0; k < layers; ++k)
        tree.updateNode(octomap::point3d(static_cast<float>(x), static_cast<float>(y),
                                         static_cast<float>((k + 0.5) * grid.resolution)),
                        v >= occupied_threshold, true);
    }
  tree.updateInnerOccupancy();
  tree.prune();
  writeFileAtomically(path, [&tree, &path](std::ostream& out) {
    if (!tree.writeBinary(out)) throw std::runtime_error(path + ": cannot write OctoMap");
  });
  return tree.getNumLeafNodes();
}

}  // namespace mrslam
