// Fusing aligned grids into one map in the reference map's frame.
//
// Rule: independent evidence adds in log-odds. Each known cell value v (percent) counts as
// logit(clamp(v / 100, 0.02, 0.98)); the merged cell is the sum over all maps that know it,
// turned back into percent. A cell no map knows stays unknown (-1). Two maps that disagree
// hard (occupied 100 vs free 0) cancel to 50, which map_saver writes as unknown: an honest
// "we do not know" rather than one map overriding the other.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "mrslam/grid.h"
#include "mrslam/packed_grid.h"

namespace mrslam::fusion {

struct PlacedGrid {
  const OccupancyGrid* grid;  // nullptr when `packed` holds the grid
  Pose2D pose;  // pose of this grid's map frame in the reference map frame
  // A packed grid is unpacked when the merge reaches its first row and dropped after its last,
  // so a map of many packed pieces never holds them all unpacked at once.
  const PackedGrid* packed = nullptr;
};

// The merged grid at the reference's resolution and orientation, covering all inputs.
OccupancyGrid mergeGrids(const OccupancyGrid& reference, const std::vector<PlacedGrid>& others);
// The same with the reference a piece like the others: the first, whose pose must be the
// identity, gives the lattice.
OccupancyGrid mergeGrids(const std::vector<PlacedGrid>& pieces);

// The steps of mergeGrids, for a caller that merges a changing set of pieces again and again
// (slam::MapComposer): the merged grid's lattice and extent (no cells); the rows of that grid a
// piece's cells can reach, first to last (first > last: none); and the merge itself, done
// again only in the rows flagged in `redo` (one flag a row of `out`, whose cells must be sized
// to its extent), leaving every other cell as it is. A row's cells depend on nothing but the
// pieces that reach it, so redoing the rows that changed pieces reach gives the whole merge's
// cells exactly. Returns the count of rows merged.
OccupancyGrid mergedExtent(const std::vector<PlacedGrid>& pieces);
std::pair<int, int> rowsReached(const PlacedGrid& piece, const OccupancyGrid& extent);
int mergeRowsInto(const std::vector<PlacedGrid>& pieces, OccupancyGrid& out, const std::vector<uint8_t>& redo);

}  // namespace mrslam::fusion
