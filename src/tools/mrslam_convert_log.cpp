// mrslam_convert_log: a robot log as mrslam reads it, written again, for benchmarks that feed
// other tools the same data (MRPT's icp-slam and rbpf-slam read rawlogs) or a slower scanner.
//
//   mrslam_convert_log IN OUT [--from N] [--every K [--phase P]] [--stamp T]
//
// IN: any log mrslam_slam_log reads. OUT: .log (CARMEN text) or .rawlog (MRPT). --from N starts
// the log at scan N (the first N scans dropped, the robot starting there). --every K then keeps
// every K-th scan (from scan P on, 0 <= P < K), the odometry of the dropped ones chained into
// the next kept scan (the raw odometry's error stays that of the full log). --stamp T stamps
// every scan and odometry reading T, as a log whose time was printed with too few digits.
// Exit 2 on bad input or a failed write.
#include <cmath>
#include <iostream>
#include <optional>
#include <string>

#include "mrslam/slam/log_writers.h"

namespace {
int fail(const std::string& message) {
  std::cerr << "mrslam_convert_log: " << message << "\n";
  return 2;
}
bool endsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}
}  // namespace

int main(int argc, char** argv) {
  const std::string usage = "usage: mrslam_convert_log IN OUT.{log,rawlog} [--from N] [--every K [--phase P]] [--stamp T]";
  std::string in, out;
  int every = 1, phase = 0, from = 0;
  std::optional<double> stamp;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--stamp") {
      if (i + 1 >= argc) return fail(a + " needs a time in seconds\n" + usage);
      try {
        size_t used = 0;
        stamp = std::stod(argv[++i], &used);
        if (used != std::string(argv[i]).size() || !std::isfinite(*stamp) || *stamp <= 0) throw std::invalid_argument("");
      } catch (...) {
        return fail(a + " needs a time in seconds above 0, got '" + std::string(argv[i]) + "'");
      }
    } else if (a == "--every" || a == "--phase" || a == "--from") {
      if (i + 1 >= argc) return fail(a + " needs a number\n" + usage);
      int& value = a == "--every" ? every : a == "--phase" ? phase : from;
      const int least = a == "--every" ? 1 : 0;
      try {
        size_t used = 0;
        value = std::stoi(argv[++i], &used);
        if (used != std::string(argv[i]).size() || value < least) throw std::invalid_argument("");
      } catch (...) {
        return fail(a + " needs a whole number >= " + std::to_string(least) + ", got '" + std::string(argv[i]) + "'");
      }
    } else if (a == "-h" || a == "--help") {
      std::cout << usage << "\n";
      return 0;
    } else if (!a.empty() && a[0] == '-') {
      return fail("unknown option " + a + "\n" + usage);
    } else if (in.empty()) {
      in = a;
    } else if (out.empty()) {
      out = a;
    } else {
      return fail("too many arguments\n" + usage);
    }
  }
  if (in.empty() || out.empty()) return fail("missing arguments\n" + usage);
  if (phase >= every) return fail("--phase must be below --every (" + std::to_string(every) + ")");
  if (!endsWith(out, ".log") && !endsWith(out, ".rawlog")) return fail(out + ": output must end in .log or .rawlog");
  try {
    mrslam::slam::RobotLog log = mrslam::slam::readRobotLog(in);
    for (const auto& note : log.notes) std::cerr << "note: " << note << "\n";
    for (const auto& w : log.warnings) std::cerr << "warning: " << w << "\n";
    if (from > 0) log = mrslam::slam::fromScan(log, static_cast<size_t>(from));
    if (every > 1) log = mrslam::slam::decimate(log, every, phase);
    if (stamp)
      for (auto& record : log.records) record.scan.stamp = *stamp;
    if (endsWith(out, ".log")) mrslam::slam::writeCarmenLog(log, out);
    else mrslam::slam::writeMrptRawlog(log, out);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  return 0;
}
