// CARMEN text logs (FLASER and ODOM lines).
//
// Odometry. In the corrected Radish logs the FLASER pose fields hold the reference (corrected)
// pose, and right after every FLASER an ODOM line with ipc timestamp 0 repeats that pose: the
// odometry is re-anchored at every scan and the ODOM lines that follow drift away from it as
// raw wheel odometry does (see ../shared/data/SOURCES.md, verified on all four logs). So the
// odometry increment between two scans is measured inside each anchored segment (segment
// start to last ODOM reading) and chained across segments; in a raw log without re-anchoring
// this is simply the increment between the ODOM readings around the two scans. The FLASER
// pose and odometry fields are kept as reference only.
#include <sstream>

#include "mrslam/slam/robot_log.h"
#include "text_lines.h"

namespace mrslam::slam {

namespace {

constexpr double kMaxJitter = 5.0;  // s

bool parseOdom(const std::string& line, Pose2D& pose, double& stamp) {
  std::istringstream in(line.substr(5));
  double tv, rv, accel;
  return static_cast<bool>(in >> pose.x >> pose.y >> pose.yaw >> tv >> rv >> accel >> stamp) &&
         std::isfinite(pose.x) && std::isfinite(pose.y) && std::isfinite(pose.yaw);
}

bool parseFlaser(const std::string& line, LaserScan& scan, Pose2D& reference) {
  std::istringstream in(line.substr(7));
  int n = 0;
  if (!(in >> n) || n <= 0 || n > 100000) return false;
  scan.ranges.resize(n);
  for (int i = 0; i < n; ++i)
    if (!(in >> scan.ranges[i])) return false;
  double ox, oy, ot;
  if (!(in >> reference.x >> reference.y >> reference.yaw >> ox >> oy >> ot >> scan.stamp)) return false;
  if (!std::isfinite(reference.x) || !std::isfinite(reference.y) || !std::isfinite(reference.yaw)) return false;
  // A 180-degree field of view: n beams at pi / n (180 or 360 beams) or pi / (n - 1) (181, 361).
  scan.angle_increment = (n % 2 == 0) ? M_PI / n : M_PI / (n - 1);
  scan.angle_min = -M_PI / 2;
  scan.range_min = 0.01;
  scan.range_max = 50.0;  // SICK LMS: 81.9 m means no return
  return true;
}

}  // namespace

RobotLog readCarmenLog(const std::string& path) {
  TextLines lines(path);
  if (!lines.isOpen()) throw LogError(path + ": cannot open");
  RobotLog log;
  log.path = path;
  log.format = "carmen";
  Pose2D since_scan;            // odometry chained over finished segments since the last scan
  Pose2D segment_start, segment_last;
  bool have_odom = false;
  std::string line;
  int number = 0;
  auto warn = [&](const std::string& what) {
    log.warnings.push_back(path + ":" + std::to_string(number) + ": " + what);
  };
  while (lines.next(line, number)) {
    if (line.rfind("ODOM ", 0) == 0) {
      Pose2D pose;
      double stamp = 0;
      if (!parseOdom(line, pose, stamp)) { warn("malformed ODOM line skipped"); continue; }
      if (!have_odom) {
        segment_start = segment_last = pose;
        have_odom = true;
      } else if (stamp == 0.0) {  // re-anchored: close the segment, start a new one here
        since_scan = since_scan.compose(segment_start.inverse().compose(segment_last));
        segment_start = segment_last = pose;
      } else {
        segment_last = pose;
      }
    } else if (line.rfind("FLASER ", 0) == 0) {
      LogRecord record;
      if (!parseFlaser(line, record.scan, record.reference)) { warn("malformed FLASER line skipped"); continue; }
      // The ipc time stamps of real logs jitter backwards by up to a second (Intel); only a
      // larger step back is a broken log.
      if (!log.records.empty() && record.scan.stamp < log.records.back().scan.stamp - kMaxJitter) {
        warn("time goes backwards, FLASER line skipped");
        continue;
      }
      record.has_reference = true;
      if (!log.records.empty() && have_odom)
        record.odometry = since_scan.compose(segment_start.inverse().compose(segment_last));
      since_scan = Pose2D{};
      segment_start = segment_last;
      log.records.push_back(std::move(record));
    }
  }
  if (log.records.empty()) throw LogError(path + ": no readable FLASER line (is this a CARMEN log?)");
  return log;
}

}  // namespace mrslam::slam
