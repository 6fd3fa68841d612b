#include "mrslam/slam/robot_log.h"

namespace mrslam::slam {

namespace {
bool endsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}
}  // namespace

RobotLog readRobotLog(const std::string& path) {
  if (endsWith(path, ".log") || endsWith(path, ".log.gz")) return readCarmenLog(path);
  if (endsWith(path, ".dat")) return readMinesLog(path);
  if (endsWith(path, ".rawlog")) return readMrptRawlog(path);
  throw LogError(path + ": unknown log format (expected .log, .log.gz, .dat or .rawlog)");
}

std::vector<Pose2D> chainOdometry(const RobotLog& log, const Pose2D& start) {
  std::vector<Pose2D> poses;
  poses.reserve(log.records.size());
  Pose2D pose = start;
  for (const LogRecord& r : log.records) poses.push_back(pose = pose.compose(r.odometry));
  return poses;
}

}  // namespace mrslam::slam
