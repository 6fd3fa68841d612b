// The front end's parameters by name, one list shared by the yaml loader (mrslam_slam_log
// --config) and the nodelets (ROS parameters), so both read config/robot.yaml the same way.
#pragma once

#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "mrslam/slam/front_end.h"

namespace mrslam::slam {

struct NamedParam {
  std::string name;
  std::variant<double*, int*, bool*, std::string*> field;
};

// Every tunable field of `p` with its name in config/robot.yaml.
std::vector<NamedParam> robotSlamParams(RobotSlamParams& p);

struct RobotParamsError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Keys of config/robot.yaml that only the nodelets read (frames, rates, topics, the
// simulated gyro's noise model); the offline loader skips them.
const std::vector<std::string>& rosLayerParamNames();

// What is wrong with values the front end cannot run on (e.g. an ICP that would never end),
// naming the keys; empty when nothing is.
std::string robotSlamParamsProblem(const RobotSlamParams& p);

// Reads the keys of robotSlamParams() from a yaml file; absent keys keep their defaults,
// keys of rosLayerParamNames() are skipped, any other unknown key, a bad value or a
// robotSlamParamsProblem() is an error naming the key.
RobotSlamParams loadRobotSlamParams(const std::string& yaml_path);

}  // namespace mrslam::slam
