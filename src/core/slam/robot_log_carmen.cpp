// CARMEN text logs: ODOM lines and the front laser's scans, as FLASER (the old format),
// ROBOTLASER1 (laser and robot pose with the scan) or RAWLASER1 (the scan alone) lines. A log
// may hold the same scans in more than one of these: the first of FLASER, ROBOTLASER1,
// RAWLASER1 that it has is read, and the others are counted in one note (RobotLog::notes).
//
// Odometry. In the corrected Radish logs the FLASER pose fields hold the reference (corrected)
// pose, and right after every FLASER an ODOM line repeats that pose: the odometry is
// re-anchored at every scan and the ODOM lines that follow drift away from it as raw wheel
// odometry does (see ../shared/data/SOURCES.md, verified on all four logs). So the odometry
// increment between two scans is measured inside each anchored segment (segment start to last
// ODOM reading) and chained across segments; in a raw log without re-anchoring this is simply
// the increment between the ODOM readings around the two scans. The FLASER pose and odometry
// fields are kept as reference only.
// A re-anchor is the first ODOM line after a scan line, known by repeating that scan's pose,
// not by its ipc timestamp 0: the four logs above give every re-anchor timestamp 0, but Radish
// logs of other buildings give many re-anchors a timestamp (Orebro all of them, as garbage such
// as 3.4e-86) or every reading timestamp 0 (Freiburg campus). Taking a re-anchor for a reading
// makes the jump from the drifted odometry to the reference pose a motion, the next scan's
// increment the reference's previous step; taking every reading for a re-anchor leaves no
// motion at all. In a raw log an ODOM line equal to the scan's pose is the same reading, where
// a re-anchor changes nothing. A RAWLASER1 line has no pose to repeat: after it, timestamp 0
// marks the re-anchor.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <vector>

#include "mrslam/slam/robot_log.h"
#include "text_lines.h"

namespace mrslam::slam {

namespace {

// Equal as printed: a re-anchor's ODOM line and its scan line write the pose alike.
bool samePose(const Pose2D& a, const Pose2D& b) {
  auto same = [](double u, double v) { return std::abs(u - v) <= 1e-6 * std::max(1.0, std::abs(u)); };
  return same(a.x, b.x) && same(a.y, b.y) && same(a.yaw, b.yaw);
}

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
  if (!plausibleCarmenLaserMax(value)) return false;
  range_max = value;
  return true;
}

// A number token as strtod reads it ("nan" and "inf" included: a bad beam, not a bad line).
bool number(const std::string& token, double& value) {
  char* end = nullptr;
  value = std::strtod(token.c_str(), &end);
  return !token.empty() && end == token.c_str() + token.size();
}

std::vector<std::string> tokensOf(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> tokens;
  for (std::string t; in >> t;) tokens.push_back(t);
  return tokens;
}

// A count token: a whole number in [0, 100000].
bool count(const std::string& token, size_t& n) {
  double v = 0;
  if (!number(token, v) || !(v >= 0 && v <= 100000) || v != std::floor(v)) return false;
  n = static_cast<size_t>(v);
  return true;
}

// FLASER n r1..rn x y theta odom_x odom_y odom_theta ipc_timestamp [host logger_timestamp]:
// the token count must agree with n, or every field after the ranges would be read shifted.
std::string parseFlaser(const std::string& line, LaserScan& scan, Pose2D& reference, double range_max) {
  const std::vector<std::string> tokens = tokensOf(line);
  size_t n = 0;
  if (tokens.size() < 2 || !count(tokens[1], n) || n < 1) return "malformed FLASER line skipped (no beam count)";
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

// ROBOTLASER1 / RAWLASER1 lines, with their own beam layout:
//   type start_angle field_of_view angular_resolution maximum_range accuracy remission_mode
//   n r1..rn m e1..em
//   [ROBOTLASER1 only: laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv
//    forward_safety_dist side_safety_dist turn_axis]
//   ipc_timestamp [host logger_timestamp]
struct RangeLine {
  LaserScan scan;
  Pose2D laser_pose, robot_pose;  // ROBOTLASER1 only
};

std::string parseRangeLine(const std::string& line, bool with_poses, double fallback_range_max, RangeLine& out) {
  const std::vector<std::string> tokens = tokensOf(line);
  const std::string what = "malformed " + tokens[0] + " line skipped";
  double header[7];
  size_t n = 0, m = 0;
  if (tokens.size() < 9) return what + " (too short)";
  for (int k = 0; k < 7; ++k)
    if (!number(tokens[1 + k], header[k]) || !std::isfinite(header[k])) return what + " (beam layout)";
  if (!count(tokens[8], n) || n < 1) return what + " (no beam count)";
  if (tokens.size() < 10 + n || !count(tokens[9 + n], m)) return what + " (no remission count after " + std::to_string(n) + " beams)";
  const size_t trailing = (with_poses ? 11 : 0) + 1;
  const size_t fields = tokens.size() >= 10 + n + m ? tokens.size() - (10 + n + m) : 0;
  if (fields != trailing && fields != trailing + 2)
    return what + " (" + std::to_string(n) + " beams and " + std::to_string(m) + " remissions announced, but the " +
           "token count does not agree)";
  const double start = header[1], resolution = header[3], max_range = header[4];
  if (!(resolution > 0) || (n - 1) * resolution > 2 * M_PI + 1e-6 || std::abs(start) > 2 * M_PI)
    return what + " (beam layout: start " + std::to_string(start) + ", resolution " + std::to_string(resolution) + ")";
  out.scan.ranges.resize(n);
  double v = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!number(tokens[9 + i], v)) return what + " (beam " + std::to_string(i) + ")";
    out.scan.ranges[i] = static_cast<float>(v);
  }
  const size_t tail = 10 + n + m;
  double t[12];
  for (size_t k = 0; k < trailing; ++k)
    if (!number(tokens[tail + k], t[k]) || !std::isfinite(t[k])) return what + " (pose or time)";
  if (with_poses) {
    out.laser_pose = {t[0], t[1], t[2]};
    out.robot_pose = {t[3], t[4], t[5]};
  }
  out.scan.stamp = t[trailing - 1];
  out.scan.angle_min = start;
  out.scan.angle_increment = resolution;
  out.scan.range_min = 0.01;
  // Readings at or beyond the maximum range are no return: the line's own, where plausible,
  // but never past the log's (PARAM, or 50 m): SICK logs write "no return" as 81.83 or 81.91 m
  // while their lines say 81.9, and a wall drawn 81.83 m out is worse than a far one lost.
  out.scan.range_max = (max_range > 1.0) ? std::min(max_range, fallback_range_max) : fallback_range_max;
  return "";
}

// The scans of one line type with the odometry chained since each one's predecessor.
struct ScanStream {
  std::vector<LogRecord> records;
  Pose2D since_scan;     // odometry chained over finished segments since the last scan
  Pose2D segment_start;  // where the current segment stood at the last scan
  Pose2D laser_in_base;  // ROBOTLASER1: read off the first line

  // The odometry segment ended at `last` and a new one starts at `anchor` (a re-anchor).
  void reanchor(const Pose2D& last, const Pose2D& anchor) {
    since_scan = since_scan.compose(segment_start.inverse().compose(last));
    segment_start = anchor;
  }
  void startAt(const Pose2D& anchor) { segment_start = anchor; }
  void add(LogRecord record, bool have_odom, const Pose2D& odom_now) {
    if (!records.empty() && have_odom) record.odometry = since_scan.compose(segment_start.inverse().compose(odom_now));
    since_scan = Pose2D{};
    segment_start = odom_now;
    records.push_back(std::move(record));
  }
};

}  // namespace

RobotLog readCarmenLog(const std::string& path) {
  TextLines lines(path);
  if (!lines.isOpen()) throw LogError(path + ": cannot open");
  RobotLog log;
  log.path = path;
  log.format = "carmen";
  enum Kind { kFlaser, kRobotLaser, kRawLaser, kKinds };
  static const char* const kNames[kKinds] = {"FLASER", "ROBOTLASER1", "RAWLASER1"};
  ScanStream streams[kKinds];
  Pose2D segment_last;  // the newest ODOM reading
  bool have_odom = false;
  // Since the last scan line no ODOM line was read; its pose fields, if it had them (a re-anchor
  // repeats them).
  bool after_scan = false, scan_has_pose = false;
  Pose2D scan_pose;
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
        for (ScanStream& s : streams) s.startAt(pose);
        have_odom = true;
      } else if (after_scan && (scan_has_pose ? samePose(pose, scan_pose) : stamp == 0.0)) {
        for (ScanStream& s : streams) s.reanchor(segment_last, pose);  // close the segment, start one here
      }
      segment_last = pose;
      after_scan = false;
    } else if (line.rfind("FLASER ", 0) == 0) {
      LogRecord record;
      const std::string problem = parseFlaser(line, record.scan, record.reference, range_max);
      if (!problem.empty()) { warn(problem); continue; }
      // Time stamps are kept as they are, even going backwards: checkTimeStamps() judges them
      // and a run falls back to the order of the lines rather than dropping scans.
      record.has_reference = true;
      scan_pose = record.reference;
      after_scan = scan_has_pose = true;
      streams[kFlaser].add(std::move(record), have_odom, segment_last);
    } else if (line.rfind("ROBOTLASER1 ", 0) == 0 || line.rfind("RAWLASER1 ", 0) == 0) {
      const Kind kind = line.rfind("ROBOTLASER1 ", 0) == 0 ? kRobotLaser : kRawLaser;
      RangeLine parsed;
      const std::string problem = parseRangeLine(line, kind == kRobotLaser, range_max, parsed);
      if (!problem.empty()) { warn(problem); continue; }
      ScanStream& stream = streams[kind];
      LogRecord record;
      record.scan = std::move(parsed.scan);
      if (kind == kRobotLaser) {
        // The robot pose is the reference (corrected logs) or the odometry (raw ones): kept for
        // evaluation only, as FLASER's; the laser's mounting is read off the first line.
        record.has_reference = true;
        record.reference = parsed.robot_pose;
        if (stream.records.empty()) stream.laser_in_base = parsed.robot_pose.inverse().compose(parsed.laser_pose);
        scan_pose = parsed.robot_pose;
      }
      after_scan = true;
      scan_has_pose = kind == kRobotLaser;
      stream.add(std::move(record), have_odom, segment_last);
    }
  }
  const std::string stopped = lines.error();
  if (!stopped.empty()) warn("input ends early (" + stopped + "): the log is truncated");
  int used = kKinds;
  for (int k = kKinds - 1; k >= 0; --k)
    if (!streams[k].records.empty()) used = k;
  if (used == kKinds)
    throw LogError(path + ": no readable FLASER, ROBOTLASER1 or RAWLASER1 line (is this a CARMEN log?)");
  for (int k = 0; k < kKinds; ++k)
    if (k != used && !streams[k].records.empty())
      log.notes.push_back(path + ": " + std::to_string(streams[k].records.size()) + " " + kNames[k] +
                             " lines left out: the log's " + kNames[used] + " lines are read");
  log.records = std::move(streams[used].records);
  log.laser_in_base = streams[used].laser_in_base;
  log.has_odometry = have_odom;
  return log;
}

}  // namespace mrslam::slam
