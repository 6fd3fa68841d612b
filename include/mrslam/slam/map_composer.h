// The robot's map composed again each time it is published, merging again only what changed.
// Between optimisations only the submap being drawn changes, yet composing every piece anew
// takes 0.9 s a map at the end of Freiburg campus (78 submaps, 5897 x 5185 cells) where the
// SLAM nodelet publishes every second. The composer keeps the last map and the pieces it was made of, and
// merges again only the bands of rows that a piece added, dropped or moved since can reach
// (fusion/grid_merge.h): the same cells as composeMap, to the bit. A new extent (a piece
// reaching past the map's edge) or moved pieces everywhere (an optimisation) merge it all.
#pragma once

#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/front_end.h"

namespace mrslam::slam {

class MapComposer {
 public:
  // composeMap(parts), kept until the next call. Not thread-safe: one caller at a time.
  const OccupancyGrid& compose(const std::vector<MapPart>& parts);
  // Rows merged by the last call (of map().height).
  int rowsMerged() const { return rows_merged_; }

 private:
  std::vector<MapPart> last_parts_;  // held, so that no new piece can reuse an old one's address
  OccupancyGrid map_;
  int rows_merged_ = 0;
};

}  // namespace mrslam::slam
