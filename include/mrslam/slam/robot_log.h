// Real recorded robot logs as one sequence of laser scans, each with the wheel-odometry
// increment since the previous scan. Readers for CARMEN (.log / .log.gz: FLASER, ROBOTLASER1
// or RAWLASER1 scans, ODOM odometry), the Mines
// ParisTech CoreSLAM .dat format and MRPT .rawlog. Bad or truncated lines are skipped
// with a warning naming the line; an unreadable file throws LogError.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/laser_scan.h"

namespace mrslam::slam {

struct LogError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct LogRecord {
  LaserScan scan;
  // Wheel odometry since the previous record's scan, in the robot frame at that scan
  // (zero for the first record).
  Pose2D odometry;
  // The log's reference pose of the robot at this scan, when it has one (the corrected
  // CARMEN logs). Used for evaluation and for the simulated IMU only, never as input.
  bool has_reference = false;
  Pose2D reference;
};

struct RobotLog {
  std::string path;
  std::string format;          // "carmen", "mines", "rawlog"
  Pose2D laser_in_base;        // the laser's mounting pose on the robot
  std::vector<LogRecord> records;
  std::vector<std::string> warnings;  // "path:line: problem" for every skipped line
  std::vector<std::string> notes;     // choices the reader made that lose nothing (not partial input)
  bool has_odometry = true;           // false: a laser-only log (no ODOM line at all)
};

// Chooses the reader from the file name (.log, .log.gz, .dat, .rawlog).
RobotLog readRobotLog(const std::string& path);

RobotLog readCarmenLog(const std::string& path);
// Whether a CARMEN log's laser maximum (PARAM robot_front_laser_max, m) is one the reader takes:
// the line is written by the tools below and read back by readCarmenLog.
inline bool plausibleCarmenLaserMax(double range) { return range > 1.0 && range < 1000.0; }
RobotLog readMinesLog(const std::string& path);
RobotLog readMrptRawlog(const std::string& path);

// Whether the scans' time stamps can be used for anything that depends on the time between
// scans: not when they are all equal (printed with too few digits), too coarse (many
// consecutive scans share one), or not increasing. `reason` says which, for one warning.
struct TimeStampCheck {
  bool usable = true;
  std::string reason;
};
TimeStampCheck checkTimeStamps(const RobotLog& log);

// Odometry chained from the log's increments, starting at `start` (one pose per record).
std::vector<Pose2D> chainOdometry(const RobotLog& log, const Pose2D& start = Pose2D{});

}  // namespace mrslam::slam
