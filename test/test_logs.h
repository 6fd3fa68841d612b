// The real logs the front-end tests share, read once per test binary.
#pragma once

#include "mrslam/slam/robot_log.h"
#include "test_data.h"

namespace mrslam::test {

inline const slam::RobotLog& intelLog() {
  static const slam::RobotLog log = slam::readRobotLog(dataPath("logs/carmen_corrected/intel-corrected.log.gz"));
  return log;
}

inline const slam::RobotLog& freiburg079Log() {
  static const slam::RobotLog log = slam::readRobotLog(dataPath("logs/carmen_corrected/freiburg-079-corrected.log.gz"));
  return log;
}

inline const slam::RobotLog& freiburg101Log() {
  static const slam::RobotLog log = slam::readRobotLog(dataPath("logs/carmen_corrected/freiburg-101-corrected.log.gz"));
  return log;
}

inline const slam::RobotLog& acesLog() {
  static const slam::RobotLog log = slam::readRobotLog(dataPath("logs/carmen_corrected/aces-corrected.log.gz"));
  return log;
}

}  // namespace mrslam::test
