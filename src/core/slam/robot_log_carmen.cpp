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
#include <cstdlib>
#include <sstream>
#include <vector>

#include "mrslam/slam/robot_log.h"
#include "text_lines.h"

namespace mrslam::slam {

namespace {

bool parseOdom(const std::string& line, Pose2D& pose, double& stamp) {
  std::istringstream in(line.substr(5));
  double tv, rv, accel;
  return static_cast<bool>(in >> pose.x >> pose.y >> pose.yaw >> tv >> rv >> accel >> stamp) &&
         std::isfinite(pose.x) && std::isfinite(pose.y) && std::isfinite(pose.yaw);
}

// The laser's maximum range from a PARAM line naming one (robot_front_laser_max and alike):
// readings at or beyond it are "no return".
bool parseLaserMax(const std::string& line, double& range_max) {
  std::istringstream in(line.substr(6));
  std::string name;
  double value = 0;
  if (!(in >> name >> value) || name.find("front_laser_max") == std::string::npos) return false;
  if (!(value > 1.0 && value < 1000.0)) return false;
  range_max = value;
  return true;
}

// A number token as strtod reads it ("nan" and "inf" included: a bad beam, not a bad line).
bool number(const std::string& token, double& value) {
  char* end = nullptr;
  value = std::strtod(token.c_str(), &end);
  return !token.empty() && end == token.c_str() + token.size();
}

// FLASER n r1..rn x y theta odom_x odom_y odom_theta ipc_timestamp [host logger_timestamp]:
// the token count must agree with n, or every field after the ranges would be read shifted.
std::string parseFlaser(const std::string& line, LaserScan& scan, Pose2D& reference, double range_max) {
  std::istringstream in(line);
  std::vector<std::string> tokens;
  for (std::string t; in >> t;) tokens.push_back(t);
  double count = 0;
  if (tokens.size() < 2 || !number(tokens[1], count) || count < 1 || count > 100000 || count != std::floor(count))
    return "malformed FLASER line skipped (no beam count)";
  const size_t n = static_cast<size_t>(count);
  const size_t fields = tokens.size() - 2;  // after "FLASER n"
  if (fields != n + 7 && fields != n + 9)
    return "malformed FLASER line skipped (" + std::to_string(n) + " beams announced, but " + std::to_string(fields) +
           " values follow the count where " + std::to_string(n + 7) + " or " + std::to_string(n + 9) + " belong)";
  scan.ranges.resize(n);
  double v[7];
  for (size_t i = 0; i < n; ++i) {
    if (!number(tokens[2 + i], v[0])) return "malformed FLASER line skipped (beam " + std::to_string(i) + ")";
    scan.ranges[i] = static_cast<float>(v[0]);
  }
  for (int k = 0; k < 7; ++k)
    if (!number(tokens[2 + n + k], v[k]) || !std::isfinite(v[k])) return "malformed FLASER line skipped (pose or time)";
  reference = {v[0], v[1], v[2]};
  scan.stamp = v[6];
  // A 180-degree field of view: n beams at pi / n (180 or 360 beams) or pi / (n - 1) (181, 361).
  scan.angle_increment = (n % 2 == 0) ? M_PI / n : M_PI / (n - 1);
  scan.angle_min = -M_PI / 2;
  scan.range_min = 0.01;
  scan.range_max = range_max;
  return "";
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
  // SICK LMS logs write no return as 81.91 m (the PARAM line says 80.99), some as 50 m.
  double range_max = 50.0;
  std::string line;
  int number = 0;
  auto warn = [&](const std::string& what) {
    log.warnings.push_back(path + ":" + std::to_string(number) + ": " + what);
  };
  while (lines.next(line, number)) {
    if (line.rfind("PARAM ", 0) == 0) {
      parseLaserMax(line, range_max);
    } else if (line.rfind("ODOM ", 0) == 0) {
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
      const std::string problem = parseFlaser(line, record.scan, record.reference, range_max);
      if (!problem.empty()) { warn(problem); continue; }
      // Time stamps are kept as they are, even going backwards: checkTimeStamps() judges them
      // and a run falls back to the order of the lines rather than dropping scans.
      record.has_reference = true;
      if (!log.records.empty() && have_odom)
        record.odometry = since_scan.compose(segment_start.inverse().compose(segment_last));
      since_scan = Pose2D{};
      segment_start = segment_last;
      log.records.push_back(std::move(record));
    }
  }
  const std::string stopped = lines.error();
  if (!stopped.empty()) warn("input ends early (" + stopped + "): the log is truncated");
  if (log.records.empty()) throw LogError(path + ": no readable FLASER line (is this a CARMEN log?)");
  log.has_odometry = have_odom;
  return log;
}

}  // namespace mrslam::slam
