// Mines ParisTech CoreSLAM logs (BreezySLAM examples exp1.dat, exp2.dat): one line per scan,
// timestamp in microseconds, fields 3 and 4 (1-based) the left and right wheel-encoder counts,
// fields 25 on the ranges in millimetres of a Hokuyo URG-04LX (682 beams over 240 degrees,
// 0 = no return). The robot model is the one published with the data (BreezySLAM mines.py):
// wheel radius 77 mm, half axle 165 mm, 2000 counts per wheel turn, laser 145 mm ahead of the
// axle centre.
#include <cmath>
#include <sstream>

#include "mrslam/slam/robot_log.h"
#include "text_lines.h"

namespace mrslam::slam {

namespace {
constexpr double kWheelRadius = 0.077, kHalfAxle = 0.165, kCountsPerTurn = 2000.0;
constexpr int kBeams = 682, kFirstRangeField = 24;
constexpr double kMaxEncoderCount = 1e15;  // counts beyond this are not an encoder's
constexpr double kFieldOfView = 240.0 * M_PI / 180.0;
}  // namespace

RobotLog readMinesLog(const std::string& path) {
  TextLines lines(path);
  if (!lines.isOpen()) throw LogError(path + ": cannot open");
  RobotLog log;
  log.path = path;
  log.format = "mines";
  log.laser_in_base = {0.145, 0.0, 0.0};
  std::string line;
  int number = 0;
  bool have_previous = false;
  long previous_left = 0, previous_right = 0;
  while (lines.next(line, number)) {
    std::istringstream in(line);
    std::vector<double> fields;
    double v;
    while (in >> v) fields.push_back(v);
    if (fields.empty()) continue;
    if (fields.size() < static_cast<size_t>(kFirstRangeField + kBeams)) {
      log.warnings.push_back(path + ":" + std::to_string(number) + ": truncated line skipped (" +
                             std::to_string(fields.size()) + " fields)");
      continue;
    }
    // Encoder counts become integers: a count that is not finite or beyond any encoder (the
    // libFuzzer target found 8.9e31) would make the conversion undefined.
    if (!(std::abs(fields[2]) < kMaxEncoderCount && std::abs(fields[3]) < kMaxEncoderCount)) {
      log.warnings.push_back(path + ":" + std::to_string(number) + ": encoder counts out of range, line skipped");
      continue;
    }
    LogRecord record;
    record.scan.stamp = fields[0] * 1e-6;
    // Time stamps are kept as they are, even going backwards: checkTimeStamps() judges them.
    const long left = static_cast<long>(fields[2]), right = static_cast<long>(fields[3]);
    if (have_previous) {
      const double wheel_left = 2 * M_PI * (left - previous_left) / kCountsPerTurn;
      const double wheel_right = 2 * M_PI * (right - previous_right) / kCountsPerTurn;
      const double distance = kWheelRadius * (wheel_left + wheel_right) / 2;
      const double turn = kWheelRadius * (wheel_right - wheel_left) / (2 * kHalfAxle);
      // Arc model: the chord of a circular arc of length `distance` turning by `turn`.
      const double half = turn / 2;
      const double chord = std::abs(turn) > 1e-9 ? distance * std::sin(half) / half : distance;
      record.odometry = {chord * std::cos(half), chord * std::sin(half), turn};
    }
    previous_left = left, previous_right = right, have_previous = true;
    record.scan.angle_min = -kFieldOfView / 2;
    record.scan.angle_increment = kFieldOfView / (kBeams - 1);
    record.scan.range_min = 0.02;
    record.scan.range_max = 5.6;
    record.scan.ranges.resize(kBeams);
    for (int i = 0; i < kBeams; ++i) record.scan.ranges[i] = static_cast<float>(fields[kFirstRangeField + i] * 1e-3);
    log.records.push_back(std::move(record));
  }
  const std::string stopped = lines.error();
  if (!stopped.empty()) log.warnings.push_back(path + ": input ends early (" + stopped + "): the log is truncated");
  if (log.records.empty()) throw LogError(path + ": no readable scan line (is this a Mines .dat log?)");
  return log;
}

}  // namespace mrslam::slam
