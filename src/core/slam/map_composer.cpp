#include "mrslam/slam/map_composer.h"

#include <algorithm>

#include "mrslam/fusion/grid_merge.h"

namespace mrslam::slam {

namespace {

bool samePiece(const MapPart& a, const MapPart& b) {
  return a.grid == b.grid && a.packed == b.packed && a.pose.x == b.pose.x && a.pose.y == b.pose.y && a.pose.yaw == b.pose.yaw;
}

bool sameExtent(const OccupancyGrid& a, const OccupancyGrid& b) {
  return a.width == b.width && a.height == b.height && a.resolution == b.resolution && a.origin.x == b.origin.x &&
         a.origin.y == b.origin.y && a.origin.yaw == b.origin.yaw;
}

std::vector<fusion::PlacedGrid> placedOf(const std::vector<MapPart>& parts) {
  std::vector<fusion::PlacedGrid> placed;
  for (const MapPart& part : parts) placed.push_back({part.grid.get(), part.pose, part.packed.get()});
  placed.front().pose = Pose2D{};  // the first piece's frame is the map frame, by composeMap's contract
  return placed;
}

// Flags the rows each piece of `parts` missing from `others` reaches.
void flagRowsOfChanged(const std::vector<MapPart>& parts, const std::vector<MapPart>& others, const OccupancyGrid& extent,
                       std::vector<uint8_t>& redo) {
  const std::vector<fusion::PlacedGrid> placed = placedOf(parts);
  for (size_t i = 0; i < parts.size(); ++i) {
    if (std::any_of(others.begin(), others.end(), [&](const MapPart& o) { return samePiece(parts[i], o); })) continue;
    const auto [first, last] = fusion::rowsReached(placed[i], extent);
    for (int r = first; r <= last; ++r) redo[static_cast<size_t>(r)] = 1;
  }
}

}  // namespace

OccupancyGrid composeMap(const std::vector<MapPart>& parts) {
  if (parts.empty()) return OccupancyGrid{};
  if (parts.size() == 1) return parts.front().grid ? *parts.front().grid : parts.front().packed->unpack();
  return fusion::mergeGrids(placedOf(parts));
}

const OccupancyGrid& MapComposer::compose(const std::vector<MapPart>& parts) {
  if (parts.size() <= 1) {  // composeMap hands a lone piece back as it is
    map_ = composeMap(parts);
    rows_merged_ = map_.height;
    last_parts_ = parts;
    return map_;
  }
  const std::vector<fusion::PlacedGrid> placed = placedOf(parts);
  OccupancyGrid extent = fusion::mergedExtent(placed);
  std::vector<uint8_t> redo(static_cast<size_t>(std::max(extent.height, 0)), 1);
  // The extent's origin is the lattice: the same extent, the same cells to merge into.
  if (last_parts_.size() > 1 && sameExtent(extent, map_)) {
    std::fill(redo.begin(), redo.end(), uint8_t{0});
    flagRowsOfChanged(parts, last_parts_, extent, redo);
    flagRowsOfChanged(last_parts_, parts, extent, redo);
  } else {
    extent.data.resize(static_cast<size_t>(extent.width) * extent.height);
    map_ = std::move(extent);
  }
  rows_merged_ = fusion::mergeRowsInto(placed, map_, redo);
  last_parts_ = parts;
  return map_;
}

}  // namespace mrslam::slam
