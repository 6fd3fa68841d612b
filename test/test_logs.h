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

// A log as a short laser would give it (a Hokuyo URG-04LX sees 5.6 m, a depth camera's fake
// laser about 4 m): every reading at or beyond `range` is "no return".
inline slam::RobotLog shortLaser(const slam::RobotLog& log, float range) {
  slam::RobotLog out = log;
  for (slam::LogRecord& r : out.records) {
    r.scan.range_max = range;
    for (float& reading : r.scan.ranges)
      if (!(reading < range)) reading = range;
  }
  return out;
}

}  // namespace mrslam::test
