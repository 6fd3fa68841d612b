#include "mrslam/slam/submap.h"

#include <algorithm>

namespace mrslam::slam {

Submap::Submap(int anchor_node, const GridMapperParams& grid, const Pose2D& laser_in_base)
    : anchor_(anchor_node), mapper_(grid, laser_in_base) {}

void Submap::insert(const LaserScan& scan, const Points2& points, const Pose2D& pose) {
  mapper_.insert(scan, pose);
  const Points2 moved = transformPoints(points, pose);
  points_.insert(points_.end(), moved.begin(), moved.end());
  min_x_ = std::min(min_x_, pose.x), max_x_ = std::max(max_x_, pose.x);
  min_y_ = std::min(min_y_, pose.y), max_y_ = std::max(max_y_, pose.y);
}

void Submap::finish(double travel) {
  finished_ = true;
  finished_travel_ = travel;
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
  if (grid_version_ != mapper_.version()) {
    grid_ = std::make_shared<const OccupancyGrid>(mapper_.toGrid());
    grid_version_ = mapper_.version();
  }
  return grid_;
}

}  // namespace mrslam::slam
