// Conversions between ROS messages/tf and the ROS-free core types (nodelets only).
#pragma once

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/OccupancyGrid.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2/utils.h>
#include <tf2_ros/buffer.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <boost/array.hpp>
#include <optional>
#include <string>

#include "mrslam/grid.h"
#include "mrslam/slam/laser_scan.h"

namespace mrslam::nodelets {

// A peer-supplied name (robot id, publisher) as it may appear in a log line: printable ASCII,
// at most 64 characters.
inline std::string printable(const std::string& name) {
  std::string out;
  for (char c : name.substr(0, 64)) out += (c >= 32 && c < 127) ? c : '?';
  return name.size() > 64 ? out + "..." : out;
}

// A frame id without tf1's leading '/' (tf2 refuses "/laser"; old bags and drivers still write it).
inline std::string bareFrame(const std::string& frame) { return !frame.empty() && frame[0] == '/' ? frame.substr(1) : frame; }

inline bool finite(const Pose2D& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.yaw); }

inline geometry_msgs::Quaternion yawToQuaternion(double yaw) {
  geometry_msgs::Quaternion q;
  q.z = std::sin(yaw / 2);
  q.w = std::cos(yaw / 2);
  return q;
}

inline Pose2D poseFromMsg(const geometry_msgs::Pose& p) {
  return {p.position.x, p.position.y, tf2::getYaw(p.orientation)};
}

inline geometry_msgs::Pose poseToMsg(const Pose2D& p) {
  geometry_msgs::Pose m;
  m.position.x = p.x;
  m.position.y = p.y;
  m.orientation = yawToQuaternion(p.yaw);
  return m;
}

inline Pose2D poseFromTransform(const geometry_msgs::Transform& t) {
  return {t.translation.x, t.translation.y, tf2::getYaw(t.rotation)};
}

inline geometry_msgs::TransformStamped transformMsg(const std::string& parent, const std::string& child,
                                                    const ros::Time& stamp, const Pose2D& p) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.transform.translation.x = p.x;
  t.transform.translation.y = p.y;
  t.transform.rotation = yawToQuaternion(p.yaw);
  return t;
}

// The transform of `child` in `parent` at `stamp` (or the latest when stamp is zero).
inline std::optional<geometry_msgs::Transform> lookupTransform(const tf2_ros::Buffer& buffer, const std::string& parent,
                                                               const std::string& child, const ros::Time& stamp,
                                                               std::string* error) {
  try {
    return buffer.lookupTransform(parent, child, stamp).transform;
  } catch (const tf2::TransformException& e) {
    if (error) *error = e.what();
    return std::nullopt;
  }
}

inline Eigen::Quaterniond quaternionOf(const geometry_msgs::Quaternion& q) { return {q.w, q.x, q.y, q.z}; }

// The pose of `child` in `parent` at `stamp` (or the latest when stamp is zero).
inline std::optional<Pose2D> lookupPose2D(const tf2_ros::Buffer& buffer, const std::string& parent,
                                          const std::string& child, const ros::Time& stamp, std::string* error) {
  const auto transform = lookupTransform(buffer, parent, child, stamp, error);
  if (!transform) return std::nullopt;
  return poseFromTransform(*transform);
}

// Why a LaserScan message cannot be used (empty when it can): on top of the core's checks,
// at most max_rays rays, and the ray count must agree with angle_min, angle_max and
// angle_increment.
inline std::string scanMsgProblem(const sensor_msgs::LaserScan& msg, size_t max_rays) {
  if (msg.ranges.size() > max_rays)
    return std::to_string(msg.ranges.size()) + " rays, more than max_rays (" + std::to_string(max_rays) + ")";
  if (msg.ranges.size() >= 2 && std::isfinite(msg.angle_increment) && msg.angle_increment != 0.0f) {
    const double expected = (static_cast<double>(msg.angle_max) - msg.angle_min) / msg.angle_increment + 1.0;
    if (std::abs(expected - static_cast<double>(msg.ranges.size())) > 1.0)
      return std::to_string(msg.ranges.size()) + " rays disagree with angle_min/angle_max/angle_increment (" +
             std::to_string(static_cast<long>(std::lround(expected))) + " expected)";
  }
  return "";
}

inline slam::LaserScan scanFromMsg(const sensor_msgs::LaserScan& msg) {
  slam::LaserScan scan;
  scan.stamp = msg.header.stamp.toSec();
  scan.angle_min = msg.angle_min;
  scan.angle_increment = msg.angle_increment;
  scan.range_min = msg.range_min;
  scan.range_max = msg.range_max;
  scan.ranges = msg.ranges;
  return scan;
}

// Why a map origin cannot be used (empty when it can): every field finite, and the rotation a
// unit quaternion about z (a grid is planar). The all-zero quaternion of a publisher that never
// set it is read as no rotation, as map_server and rviz do.
inline std::string originMsgProblem(const geometry_msgs::Pose& o) {
  const auto& q = o.orientation;
  for (double v : {o.position.x, o.position.y, o.position.z, q.x, q.y, q.z, q.w})
    if (!std::isfinite(v)) return "origin is not finite";
  const double norm = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  if (norm == 0.0) return "";
  if (std::abs(norm - 1.0) > 1e-3) return "origin orientation is not a unit quaternion (norm " + std::to_string(norm) + ")";
  if (std::hypot(q.x, q.y) > 1e-3) return "origin orientation is not a rotation about z";
  return "";
}

// Why a grid's geometry cannot be used (empty when it can): resolution, size limit, origin.
inline std::string gridInfoProblem(const nav_msgs::MapMetaData& info, int64_t max_cells) {
  if (!std::isfinite(info.resolution) || !(info.resolution > 0)) return "resolution is not positive";
  if (info.width == 0 || info.height == 0) return "empty grid";
  // Compared by division: width x height of two 32-bit fields can overflow a 64-bit product.
  if (info.width > max_cells || info.height > max_cells / info.width)
    return "absurd size " + std::to_string(info.width) + " x " + std::to_string(info.height);
  return originMsgProblem(info.origin);
}

// Why a grid message cannot be used (empty when it can): its geometry, its data size.
inline std::string gridMsgProblem(const nav_msgs::OccupancyGrid& msg, int64_t max_cells) {
  const std::string problem = gridInfoProblem(msg.info, max_cells);
  if (!problem.empty()) return problem;
  const int64_t cells = static_cast<int64_t>(msg.info.width) * msg.info.height;
  if (static_cast<int64_t>(msg.data.size()) != cells)
    return "data size " + std::to_string(msg.data.size()) + " != width x height " + std::to_string(cells);
  return "";
}

inline OccupancyGrid gridFromMsg(const nav_msgs::OccupancyGrid& msg) {
  OccupancyGrid grid;
  grid.width = static_cast<int>(msg.info.width);
  grid.height = static_cast<int>(msg.info.height);
  grid.resolution = msg.info.resolution;
  grid.origin = poseFromMsg(msg.info.origin);
  grid.data = msg.data;
  return grid;
}

// Header and info of `msg` from `grid`, and its cells unless with_data is false (the caller
// moved them in already).
inline void gridToMsg(const OccupancyGrid& grid, const std::string& frame, const ros::Time& stamp,
                      nav_msgs::OccupancyGrid& msg, bool with_data = true) {
  msg.header.stamp = stamp;
  msg.header.frame_id = frame;
  msg.info.map_load_time = stamp;
  msg.info.resolution = static_cast<float>(grid.resolution);
  msg.info.width = static_cast<uint32_t>(grid.width);
  msg.info.height = static_cast<uint32_t>(grid.height);
  msg.info.origin = poseToMsg(grid.origin);
  if (with_data) msg.data = grid.data;
}

// Row-major 6x6 (x, y, z, roll, pitch, yaw) from the 3x3 (x, y, yaw) covariance.
inline void fillCovariance(const Eigen::Matrix3d& cov, boost::array<double, 36>& out) {
  out.fill(0.0);
  const int index[3] = {0, 1, 5};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out[index[r] * 6 + index[c]] = cov(r, c);
}

}  // namespace mrslam::nodelets
