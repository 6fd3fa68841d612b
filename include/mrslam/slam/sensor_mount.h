// How a laser and a gyro sit on the robot, from the full 3D rotation of their frames in
// base_frame (tf), reduced to what a planar front end needs.
//
// A planar front end needs the laser's pose in the floor's plane and the robot's yaw rate. Taking
// only the yaw of the laser's tf (tf2::getYaw) reads a laser mounted upside down (rolled 180
// degrees, a common mounting under a robot's top plate) as an upright one and mirrors every scan,
// and taking a gyro's angular_velocity.z in its own frame reads one mounted upside down, or on
// its side, with the wrong sign or as no turn at all. Both maps came out wrong without a word.
// slam_toolbox and gmapping detect the inverted laser the same way (where the laser's z axis
// points); robot_localization turns IMU data into base_frame through tf as done here.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <string>

#include "mrslam/grid.h"
#include "mrslam/slam/laser_scan.h"

namespace mrslam::slam {

struct LaserMount {
  Pose2D pose;               // the laser's origin and heading (its x axis) in base_frame's plane
  bool upside_down = false;  // its z axis points down: beams sweep the other way round
};

// The scan plane may lean this far from the floor's (either side up); a laser tilted further
// sees the floor and ceiling, not walls, and is refused.
constexpr double kMaxLaserTiltDeg = 30.0;

// The mount of a laser whose frame has `rotation` and origin (x, y) in base_frame; nothing, and
// `problem` says why, when its scan plane is tilted beyond kMaxLaserTiltDeg or the rotation is
// not finite.
std::optional<LaserMount> laserMount(const Eigen::Quaterniond& rotation, double x, double y, std::string* problem);

// The scan an upright laser at the same pose would have reported for the same beams, in the
// order it lists them: an upside-down laser's beam at angle a points at -a in the upright frame.
LaserScan uprightScan(LaserScan scan);

// The robot's yaw rate (about base_frame's z axis) from a gyro's angular velocity in its own
// frame, which has `rotation` in base_frame.
double baseYawRate(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& angular_velocity);

}  // namespace mrslam::slam
