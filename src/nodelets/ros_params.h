// Reads the front end's parameters (config/robot.yaml, loaded into the nodelet's private
// namespace) by the names the offline loader uses, so both read the same file the same way.
#pragma once

#include <ros/node_handle.h>

#include <variant>

#include "mrslam/slam/robot_params.h"

namespace mrslam::nodelets {

inline slam::RobotSlamParams robotSlamParamsFrom(const ros::NodeHandle& private_nh) {
  slam::RobotSlamParams p;
  for (const slam::NamedParam& named : slam::robotSlamParams(p))
    std::visit([&](auto* field) { private_nh.param(named.name, *field, *field); }, named.field);
  return p;
}

}  // namespace mrslam::nodelets
