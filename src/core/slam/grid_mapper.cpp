#include "mrslam/slam/grid_mapper.h"

#include <algorithm>

#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/poses/CPose3D.h>

namespace mrslam::slam {

struct GridMapper::Impl {
  // One cell until setSize(): MRPT's default map is 40 m square (640 000 cells at 5 cm).
  explicit Impl(float resolution) : map(0, resolution, 0, resolution, resolution) {}
  mrpt::maps::COccupancyGridMap2D map;
};

GridMapper::GridMapper(const GridMapperParams& params, const Pose2D& laser_in_base)
    : params_(params), laser_in_base_(laser_in_base), impl_(std::make_unique<Impl>(static_cast<float>(params.resolution))) {
  clear();
}

GridMapper::~GridMapper() = default;

void GridMapper::clear() {
  const float half = static_cast<float>(params_.initial_size / 2);
  auto& map = impl_->map;
  map.setSize(-half, half, -half, half, static_cast<float>(params_.resolution), 0.5f);
  auto& o = map.insertionOptions;
  o.maxDistanceInsertion = static_cast<float>(params_.max_insert_range);
  o.maxOccupancyUpdateCertainty = static_cast<float>(params_.occupied_update);
  o.maxFreenessUpdateCertainty = static_cast<float>(1.0 - params_.free_update);
  o.considerInvalidRangesAsFreeSpace = false;  // a NaN or "no return" says nothing
  o.wideningBeamsWithDistance = false;
  ++version_;
}

void GridMapper::release() {
  impl_ = std::make_unique<Impl>(static_cast<float>(params_.resolution));  // setSize() keeps capacity
}

namespace {

// The scan as MRPT's observation: rays spread evenly over an aperture centred on the sensor's
// x axis (so the sensor pose is turned to the centre of our scan's span), `use` choosing the
// beams that count, each at the range `range_of` gives.
template <typename Use, typename Range>
mrpt::obs::CObservation2DRangeScan observation(const LaserScan& scan, const Pose2D& laser_in_base, Use use, Range range_of) {
  mrpt::obs::CObservation2DRangeScan obs;
  const size_t n = scan.ranges.size();
  const double span = scan.angle_increment * (n - 1);
  obs.aperture = static_cast<float>(std::abs(span));
  obs.rightToLeft = span > 0;
  obs.maxRange = static_cast<float>(scan.range_max);
  obs.resizeScan(n);
  for (size_t i = 0; i < n; ++i) {
    const bool valid = use(scan.ranges[i]);
    obs.setScanRange(i, valid ? range_of(scan.ranges[i]) : 0.0f);
    obs.setScanRangeValidity(i, valid);
  }
  const Pose2D sensor = laser_in_base.compose(Pose2D{0, 0, scan.angle_min + span / 2});
  obs.sensorPose = mrpt::poses::CPose3D(sensor.x, sensor.y, 0, sensor.yaw, 0, 0);
  return obs;
}

}  // namespace

void GridMapper::insert(const LaserScan& scan, const Pose2D& pose) {
  if (!scanProblem(scan).empty() || scan.ranges.size() < 2) return;
  auto& map = impl_->map;
  const mrpt::poses::CPose3D robot(pose.x, pose.y, 0, pose.yaw, 0, 0);
  auto is_return = [&](float r) { return isReturn(scan, r); };
  map.insertObservation(observation(scan, laser_in_base_, is_return, [](float r) { return r; }), robot);
  // No return (at or beyond the sensor's maximum) says the beam met nothing up to a cap: free
  // space, never an obstacle. MRPT marks no end cell for a ray truncated at
  // maxDistanceInsertion, so these rays go in with exactly that length.
  const float cap = static_cast<float>(params_.no_return_range);
  auto is_no_return = [&](float r) { return isNoReturn(scan, r); };
  if (cap > 0 && std::any_of(scan.ranges.begin(), scan.ranges.end(), is_no_return)) {
    map.insertionOptions.maxDistanceInsertion = cap;
    map.insertObservation(observation(scan, laser_in_base_, is_no_return, [cap](float) { return cap; }), robot);
    map.insertionOptions.maxDistanceInsertion = static_cast<float>(params_.max_insert_range);
  }
  ++version_;
}

GridGeometry GridMapper::geometry() const {
  const auto& map = impl_->map;
  GridGeometry g;
  g.width = static_cast<int>(map.getSizeX());
  g.height = static_cast<int>(map.getSizeY());
  g.resolution = map.getResolution();
  g.origin = {map.getXMin(), map.getYMin(), 0.0};
  return g;
}

namespace {

// Log-odds 0 is a cell no ray has touched (updates never land exactly on 0 in practice).
int8_t percent(mrpt::maps::COccupancyGridMap2D::cellType logodds) {
  return logodds == 0 ? OccupancyGrid::kUnknown
                      : static_cast<int8_t>(std::lround(100.0f * (1.0f - mrpt::maps::COccupancyGridMap2D::l2p(logodds))));
}

}  // namespace

void GridMapper::exportCells(int8_t* cells) const {
  const auto& raw = impl_->map.getRawMap();
  for (size_t i = 0; i < raw.size(); ++i) cells[i] = percent(raw[i]);
}

OccupancyGrid GridMapper::toKnownGrid() const {
  const GridGeometry g = geometry();
  const auto& raw = impl_->map.getRawMap();
  int x0 = g.width, x1 = -1, y0 = g.height, y1 = -1;
  for (int y = 0; y < g.height; ++y) {
    const auto* row = &raw[static_cast<size_t>(y) * g.width];
    int first = 0, last = g.width - 1;
    while (first < g.width && row[first] == 0) ++first;
    if (first == g.width) continue;
    while (row[last] == 0) --last;
    x0 = std::min(x0, first), x1 = std::max(x1, last), y0 = std::min(y0, y), y1 = y;
  }
  OccupancyGrid grid;
  grid.resolution = g.resolution;
  grid.origin = g.origin;
  if (x1 < 0) {  // nothing known: one unknown cell
    grid.width = grid.height = 1;
    grid.data.assign(1, OccupancyGrid::kUnknown);
    return grid;
  }
  grid.width = x1 - x0 + 1;
  grid.height = y1 - y0 + 1;
  grid.origin = {g.origin.x + x0 * g.resolution, g.origin.y + y0 * g.resolution, 0.0};
  grid.data.resize(static_cast<size_t>(grid.width) * grid.height);
  for (int y = 0; y < grid.height; ++y) {
    const auto* row = &raw[static_cast<size_t>(y + y0) * g.width + x0];
    int8_t* out = &grid.data[static_cast<size_t>(y) * grid.width];
    for (int x = 0; x < grid.width; ++x) out[x] = percent(row[x]);
  }
  return grid;
}

OccupancyGrid GridMapper::toGrid() const {
  const GridGeometry g = geometry();
  OccupancyGrid grid;
  grid.width = g.width;
  grid.height = g.height;
  grid.resolution = g.resolution;
  grid.origin = g.origin;
  grid.data.resize(static_cast<size_t>(g.width) * g.height);
  exportCells(grid.data.data());
  return grid;
}

}  // namespace mrslam::slam
