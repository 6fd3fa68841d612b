#include "mrslam/slam/submap.h"

#include <algorithm>
#include <cmath>

namespace mrslam::slam {

Submap::Submap(int anchor_node, const GridMapperParams& grid, const Pose2D& laser_in_base, double points_resolution)
    : anchor_(anchor_node), mapper_(grid, laser_in_base), laser_in_base_(laser_in_base),
      points_resolution_(points_resolution) {}

void Submap::insert(const LaserScan& scan, int node, const Pose2D& offset, const Pose2D& tracked, const Pose2D& drawn) {
  scans_.push_back({scan, node, offset, drawn.compose(offset)});
  mapper_.insert(scan, scans_.back().pose);
  const Pose2D pose = tracked.compose(offset);
  const Points2 moved = transformPoints(thinPoints(scanPoints(scan, laser_in_base_), points_resolution_), pose);
  points_.insert(points_.end(), moved.begin(), moved.end());
  min_x_ = std::min(min_x_, pose.x), max_x_ = std::max(max_x_, pose.x);
  min_y_ = std::min(min_y_, pose.y), max_y_ = std::max(max_y_, pose.y);
}

bool Submap::follow(const std::vector<Pose2D>& node_poses, double xy, double yaw) {
  if (node_poses.size() != nodes_.size() || scans_.empty()) return false;
  const int first = nodes_.front().first;
  const auto now = [&](const Drawn& d) { return node_poses[static_cast<size_t>(d.node - first)].compose(d.offset); };
  const bool moved = std::any_of(scans_.begin(), scans_.end(), [&](const Drawn& d) {
    const Pose2D shift = d.pose.inverse().compose(now(d));
    return std::hypot(shift.x, shift.y) > xy || std::abs(shift.yaw) > yaw;
  });
  if (!moved) return false;
  packed_.reset();
  mapper_.clear();
  for (Drawn& d : scans_) {
    d.pose = now(d);
    mapper_.insert(d.scan, d.pose);
  }
  if (finished_) freeze();
  return true;
}

void Submap::finish(double travel) {
  finished_ = true;
  finished_travel_ = travel;
  freeze();
}

const std::pair<int, Pose2D>& Submap::nearestNode(double x, double y) const {
  return *std::min_element(nodes_.begin(), nodes_.end(), [&](const auto& a, const auto& b) {
    return std::hypot(a.second.x - x, a.second.y - y) < std::hypot(b.second.x - x, b.second.y - y);
  });
}

void Submap::poseCircle(double& cx, double& cy, double& radius) const {
  if (min_x_ > max_x_) {
    cx = cy = radius = 0;
    return;
  }
  cx = (min_x_ + max_x_) / 2, cy = (min_y_ + max_y_) / 2;
  radius = std::hypot(max_x_ - min_x_, max_y_ - min_y_) / 2;
}

std::shared_ptr<const OccupancyGrid> Submap::grid() const {
  if (packed_) return std::make_shared<const OccupancyGrid>(packed_->unpack());
  if (grid_version_ != mapper_.version()) {
    grid_ = std::make_shared<const OccupancyGrid>(mapper_.toKnownGrid());
    grid_version_ = mapper_.version();
  }
  return grid_;
}

MapPart Submap::part(const Pose2D& anchor_pose) const {
  if (packed_) return {nullptr, anchor_pose, packed_};
  return {grid(), anchor_pose, nullptr};
}

size_t Submap::gridBytes() const {
  const GridGeometry g = mapper_.geometry();
  return static_cast<size_t>(g.width) * g.height + (grid_ ? grid_->data.size() : 0) + (packed_ ? packed_->bytes() : 0);
}

void Submap::freeze() {
  packed_ = std::make_shared<const PackedGrid>(*grid());
  grid_.reset();
  grid_version_ = ~0ull;
  mapper_.release();
}

}  // namespace mrslam::slam
