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

TimeStampCheck checkTimeStamps(const RobotLog& log) {
  const size_t n = log.records.size();
  if (n < 2) return {};
  size_t equal = 0, back = 0;
  for (size_t k = 1; k < n; ++k) {
    const double dt = log.records[k].scan.stamp - log.records[k - 1].scan.stamp;
    equal += dt == 0.0;
    back += dt < 0.0;
  }
  const size_t steps = n - 1;
  if (equal == steps)
    return {false, "all " + std::to_string(n) + " scans have the same time stamp"};
  // Real logs jitter: a few equal or backward steps are normal (Intel's ipc stamps step back
  // by up to a second now and then).
  if (back * 20 > steps)
    return {false, "time stamps go backwards at " + std::to_string(back) + " of " + std::to_string(n) + " scans"};
  if (equal * 5 > steps)
    return {false, std::to_string(equal) + " of " + std::to_string(n) + " scans share their time stamp with the previous one (too coarse)"};
  return {};
}

std::vector<Pose2D> chainOdometry(const RobotLog& log, const Pose2D& start) {
  std::vector<Pose2D> poses;
  poses.reserve(log.records.size());
  Pose2D pose = start;
  for (const LogRecord& r : log.records) poses.push_back(pose = pose.compose(r.odometry));
  return poses;
}

}  // namespace mrslam::slam
