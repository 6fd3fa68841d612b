// mrslam_slam_log: runs one robot's front end (the core the nodelets use) on a recorded log,
// no ROS master needed.
//
//   mrslam_slam_log LOG --trajectory OUT.txt [--map OUT.yaml [--png]] [--config robot.yaml]
//                   [--simulated-imu [--imu-seed N]] [--no-scan-matching] [--stats]
//                   [--window START:END]
//
// LOG: CARMEN .log/.log.gz (odometry from the ODOM lines; the FLASER poses are the reference
// and never input), Mines .dat, MRPT .rawlog. OUT.txt gets one line per scan used,
// "timestamp x y yaw" (base_link in the robot's map frame, which is its pose at the first scan).
// --simulated-imu feeds a SIMULATED MEMS gyro made from the log's reference trajectory (logs
// with reference poses only). Bad lines are warned about and skipped; exit 2 on bad input.
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "mrslam/map_io.h"
#include "mrslam/slam/robot_log.h"
#include "mrslam/slam/robot_params.h"
#include "mrslam/slam/front_end.h"
#include "mrslam/slam/simulated_gyro.h"

namespace {

constexpr const char* kUsage =
    "usage: mrslam_slam_log LOG --trajectory OUT.txt [--map OUT.yaml [--png]] [--config robot.yaml]\n"
    "                       [--simulated-imu [--imu-seed N]] [--no-scan-matching] [--stats] [--window START:END]\n";

int fail(const std::string& message) {
  std::cerr << "mrslam_slam_log: " << message << "\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  namespace slam = mrslam::slam;
  std::string log_path, trajectory_path, map_path, config_path;
  bool simulated_imu = false, scan_matching = true, loop_closure = true, stats = false, png = false;
  unsigned imu_seed = 1;
  double window_start = 0, window_end = 0;  // seconds after the log's first scan; end 0 = to the end
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](std::string& out) {
      if (i + 1 >= argc) return false;
      out = argv[++i];
      return true;
    };
    std::string seed;
    if (a == "--trajectory") { if (!value(trajectory_path)) return fail("--trajectory needs a file\n" + std::string(kUsage)); }
    else if (a == "--map") { if (!value(map_path)) return fail("--map needs a file"); }
    else if (a == "--config") { if (!value(config_path)) return fail("--config needs a file"); }
    else if (a == "--imu-seed") {
      if (!value(seed)) return fail("--imu-seed needs a number");
      try { imu_seed = static_cast<unsigned>(std::stoul(seed)); } catch (...) { return fail("--imu-seed needs a number"); }
    }
    else if (a == "--window") {
      std::string spec;
      if (!value(spec) || spec.find(':') == std::string::npos) return fail("--window needs START:END (seconds)");
      try {
        window_start = std::stod(spec.substr(0, spec.find(':')));
        window_end = std::stod(spec.substr(spec.find(':') + 1));
      } catch (...) { return fail("--window needs START:END (seconds)"); }
    }
    else if (a == "--simulated-imu") simulated_imu = true;
    else if (a == "--no-scan-matching") scan_matching = false;
    else if (a == "--no-loop-closure") loop_closure = false;
    else if (a == "--stats") stats = true;
    else if (a == "--png") png = true;
    else if (a == "-h" || a == "--help") { std::cout << kUsage; return 0; }
    else if (!a.empty() && a[0] == '-') return fail("unknown option " + a + "\n" + kUsage);
    else if (log_path.empty()) log_path = a;
    else return fail("only one log can be given\n" + std::string(kUsage));
  }
  if (log_path.empty() || trajectory_path.empty()) return fail(std::string("missing arguments\n") + kUsage);

  slam::RobotSlamParams params;
  try {
    if (!config_path.empty()) params = slam::loadRobotSlamParams(config_path);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  params.use_scan_matching = params.use_scan_matching && scan_matching;
  params.use_imu = simulated_imu;
  params.loop_closure = params.loop_closure && loop_closure;

  const auto wall_start = std::chrono::steady_clock::now();
  slam::RobotLog log;
  try {
    log = slam::readRobotLog(log_path);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  for (size_t i = 0; i < log.warnings.size() && i < 20; ++i) std::cerr << "warning: " << log.warnings[i] << "\n";
  if (log.warnings.size() > 20) std::cerr << "warning: ... " << log.warnings.size() - 20 << " more lines skipped\n";
  if (simulated_imu && !log.records.front().has_reference)
    return fail(log_path + ": --simulated-imu needs a log with reference poses (the corrected CARMEN logs)");

  std::ofstream trajectory(trajectory_path);
  if (!trajectory) return fail(trajectory_path + ": cannot write");
  trajectory << std::fixed << std::setprecision(6);

  const std::unique_ptr<slam::FrontEnd> front_end = slam::makeFrontEnd(params, log.laser_in_base);
  slam::FrontEnd& robot = *front_end;
  std::vector<double> stamps;
  slam::SimulatedGyro gyro(slam::GyroNoiseModel{}, imu_seed);
  double first_stamp = 0, last_stamp = 0;
  size_t used = 0, matched = 0, gated = 0, imu_used = 0, jumps = 0;
  const double log_start = log.records.front().scan.stamp;
  size_t first_in_window = log.records.size();
  for (size_t k = 0; k < log.records.size(); ++k) {
    const slam::LogRecord& r = log.records[k];
    const double t_log = r.scan.stamp - log_start;
    if (t_log < window_start || (window_end > 0 && t_log > window_end)) continue;
    if (first_in_window == log.records.size()) {
      first_in_window = k;
      if (r.has_reference && (window_start > 0 || window_end > 0))  // where this window's map frame sits in the log's frame
        std::cerr << "window starts at scan " << k << ", reference pose " << r.reference.x << " " << r.reference.y << " "
                  << r.reference.yaw << "\n";
    } else {
      robot.addOdometry(r.odometry);
    }
    if (simulated_imu && k > first_in_window) {
      const double t0 = log.records[k - 1].scan.stamp, t1 = r.scan.stamp;
      const double true_change = mrslam::Pose2D::normalizeAngle(r.reference.yaw - log.records[k - 1].reference.yaw);
      if (t1 > t0) robot.addGyro(gyro.integratedYaw(t0, t1, true_change), gyro.integratedVariance(t1 - t0));
    }
    const slam::ScanStep step = robot.processScan(r.scan);
    if (!step.used) {
      std::cerr << "warning: " << log_path << ": scan " << k << " not used: " << step.reason << "\n";
      continue;
    }
    if (used++ == 0) first_stamp = r.scan.stamp;
    last_stamp = r.scan.stamp;
    matched += step.matched;
    gated += step.gated;
    imu_used += step.imu_used;
    jumps += step.odometry_jump;
    stamps.push_back(r.scan.stamp);
  }
  // The final estimate of every scan's pose (loop closures move earlier ones).
  const std::vector<mrslam::Pose2D> poses = robot.trajectory();
  for (size_t i = 0; i < poses.size() && i < stamps.size(); ++i)
    trajectory << stamps[i] << ' ' << poses[i].x << ' ' << poses[i].y << ' ' << poses[i].yaw << '\n';
  trajectory.close();
  if (!trajectory) return fail(trajectory_path + ": write failed");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();

  if (!map_path.empty()) {
    try {
      mrslam::saveMap(robot.map(), map_path, png ? ".png" : ".pgm");
    } catch (const std::exception& e) {
      return fail(e.what());
    }
  }
  if (stats) {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    const double duration = last_stamp - first_stamp;
    std::cout << std::fixed << std::setprecision(1) << "scans " << used << " matched " << matched << " gated " << gated
              << " imu " << imu_used << " odometry_jumps " << jumps << " loop_closures " << robot.stats().loop_accepted
              << " seconds " << std::setprecision(3) << seconds
              << " scans_per_s " << std::setprecision(1) << used / seconds << " log_s " << duration
              << " x_realtime " << duration / seconds << " peak_mb " << usage.ru_maxrss / 1024.0 << "\n";
  }
  return 0;
}
