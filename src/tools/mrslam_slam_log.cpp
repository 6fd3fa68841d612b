// mrslam_slam_log: runs one robot's SLAM (the core the SLAM nodelet uses) on a recorded log, no
// ROS master needed.
//
//   mrslam_slam_log LOG --trajectory OUT.txt [--map OUT.yaml [--png]] [--config robot.yaml]
//                   [--simulated-imu [--imu-seed N]] [--no-scan-matching] [--no-loop-closure]
//                   [--window START:END | --scans FIRST:LAST] [--allow-partial] [--stats]
//
// LOG: CARMEN .log/.log.gz (scans from FLASER, ROBOTLASER1 or RAWLASER1 lines; odometry from
// the ODOM lines; the scan lines' robot poses are the reference and never input), Mines .dat,
// MRPT .rawlog. --window runs the scans of a stretch of time, --scans those of a stretch of the
// log's lines (indices as in OUT.txt, LAST included; a log whose time stamps are unusable can
// only be cut this way). OUT.txt gets one line per scan used,
// "timestamp x y yaw scan": base_link in the robot's map frame (its pose at the first scan),
// the final estimate after every loop closure, and the scan's index in the log. --simulated-imu
// feeds a SIMULATED MEMS gyro made from the log's reference trajectory (logs with reference
// poses only).
//
// Honest about its input: time stamps that are all equal, too coarse or not increasing are
// reported once and not used (no rule then depends on the time between scans); a closing
// summary on stderr says what the run used, matched, rejected and closed, and warns loudly
// when most of it failed. Exit status: 0 done; 2 bad input or a failed write; 3 partial input
// (lines skipped, file truncated) unless --allow-partial.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "mrslam/map_io.h"
#include "mrslam/slam/front_end.h"
#include "mrslam/slam/robot_log.h"
#include "mrslam/slam/robot_params.h"
#include "mrslam/slam/simulated_gyro.h"

namespace {

namespace slam = mrslam::slam;

constexpr const char* kUsage =
    "usage: mrslam_slam_log LOG --trajectory OUT.txt [--map OUT.yaml [--png]] [--config robot.yaml]\n"
    "                       [--simulated-imu [--imu-seed N]] [--no-scan-matching] [--no-loop-closure]\n"
    "                       [--window START:END | --scans FIRST:LAST] [--allow-partial] [--stats]\n";

constexpr int kBadInput = 2, kPartialInput = 3;

int fail(const std::string& message) {
  std::cerr << "mrslam_slam_log: " << message << "\n";
  return kBadInput;
}

struct Options {
  std::string log_path, trajectory_path, map_path, config_path;
  bool simulated_imu = false, scan_matching = true, loop_closure = true, stats = false, png = false;
  bool allow_partial = false;
  unsigned imu_seed = 1;
  double window_start = 0, window_end = 0;  // seconds after the log's first scan; end 0 = to the end
  bool windowed = false;
  size_t first_scan = 0, last_scan = 0;  // --scans: indices in the log, last included; last 0 = to the end
  bool scan_window = false;
  bool cut() const { return windowed || scan_window; }
  // Whether scan `k`, taken `t_log` s after the log's first, lies outside the window asked for.
  bool outside(size_t k, double t_log) const {
    if (windowed) return t_log < window_start || (window_end > 0 && t_log > window_end);
    if (scan_window) return k < first_scan || (last_scan > 0 && k > last_scan);
    return false;
  }
};

// FIRST:LAST as two scan indices into `first` and `last`; false when it is not that.
bool parseScanRange(const std::string& text, size_t& first, size_t& last) {
  const size_t colon = text.find(':');
  if (colon == std::string::npos) return false;
  const std::string a = text.substr(0, colon), b = text.substr(colon + 1);
  const auto digits = [](const std::string& t) {
    return !t.empty() && t.size() <= 9 && t.find_first_not_of("0123456789") == std::string::npos;
  };
  if (!digits(a) || !digits(b)) return false;
  first = std::stoul(a), last = std::stoul(b);
  return true;
}

// Parses the command line; an empty string when it is usable, else the problem.
std::string parseOptions(int argc, char** argv, Options& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](std::string& out) {
      if (i + 1 >= argc) return false;
      out = argv[++i];
      return true;
    };
    std::string text;
    if (a == "--trajectory") {
      if (!value(o.trajectory_path)) return "--trajectory needs a file";
    } else if (a == "--map") {
      if (!value(o.map_path)) return "--map needs a file";
    } else if (a == "--config") {
      if (!value(o.config_path)) return "--config needs a file";
    } else if (a == "--imu-seed") {
      if (!value(text)) return "--imu-seed needs a number";
      try { o.imu_seed = static_cast<unsigned>(std::stoul(text)); } catch (...) { return "--imu-seed needs a number"; }
    } else if (a == "--window") {
      if (!value(text) || text.find(':') == std::string::npos) return "--window needs START:END (seconds)";
      try {
        o.window_start = std::stod(text.substr(0, text.find(':')));
        o.window_end = std::stod(text.substr(text.find(':') + 1));
      } catch (...) {
        return "--window needs START:END (seconds), got '" + text + "'";
      }
      if (!std::isfinite(o.window_start) || !std::isfinite(o.window_end) || o.window_start < 0 ||
          (o.window_end != 0 && o.window_end <= o.window_start))
        return "--window " + text + ": START must be >= 0 and END after START (or 0: to the end)";
      o.windowed = true;
    } else if (a == "--scans") {
      if (!value(text) || !parseScanRange(text, o.first_scan, o.last_scan))
        return "--scans needs FIRST:LAST (scan indices in the log)" + (text.empty() ? std::string() : ", got '" + text + "'");
      if (o.last_scan != 0 && o.last_scan <= o.first_scan)
        return "--scans " + text + ": LAST must come after FIRST (or be 0: to the end)";
      o.scan_window = true;
    } else if (a == "--simulated-imu") {
      o.simulated_imu = true;
    } else if (a == "--no-scan-matching") {
      o.scan_matching = false;
    } else if (a == "--no-loop-closure") {
      o.loop_closure = false;
    } else if (a == "--allow-partial") {
      o.allow_partial = true;
    } else if (a == "--stats") {
      o.stats = true;
    } else if (a == "--png") {
      o.png = true;
    } else if (!a.empty() && a[0] == '-') {
      return "unknown option " + a;
    } else if (o.log_path.empty()) {
      o.log_path = a;
    } else {
      return "only one log can be given";
    }
  }
  if (o.log_path.empty() || o.trajectory_path.empty()) return "missing arguments";
  if (o.windowed && o.scan_window) return "--window and --scans cannot be combined: cut by time or by scans";
  return "";
}

struct UsedScan {
  size_t index;  // in the log
  double stamp;
};

// What the run did, in a few lines on stderr; loud when most of it failed.
void printSummary(const Options& o, const slam::FrontEnd& robot, size_t scans_in_log, size_t offered) {
  const slam::FrontEndStats s = robot.stats();
  std::ostringstream out;
  out << "mrslam_slam_log: " << o.log_path << ": " << s.used << " of " << offered << " scans used";
  if (offered != scans_in_log) out << " (window of " << scans_in_log << ")";
  out << ", " << s.matched << " matched, " << s.rejected << " rejected";
  if (!s.last_problem.empty() && s.rejected) out << " (last: " << s.last_problem << ")";
  out << "; odometry doubted " << s.odometry_doubted << ", jumps " << s.odometry_jumps << ", slips " << s.odometry_slips
      << ", driven backwards " << s.odometry_reversals << ", turns it missed " << s.odometry_missed_turns
      << " (and " << s.odometry_turns_doubted << " doubted); "
      << s.seeds_alone << " placed by the correlative search alone";
  if (s.searches_given_up)
    out << "; " << s.searches_given_up << " correlative searches given up (the map scores alike everywhere: a lost track?)";
  if (robot.name() == "graph")
    out << "\nmrslam_slam_log: graph " << s.nodes << " nodes, " << s.submaps << " submaps (" << s.submaps_redrawn << " redrawn); loop closures "
        << s.loop_accepted << " accepted of " << s.loop_attempts << " tried (rejected: " << s.loop_rejected_score
        << " score, " << s.loop_rejected_ambiguous << " ambiguous, " << s.loop_rejected_icp << " ICP; "
        << s.loop_unconfirmed << " never confirmed; " << s.loop_dropped << " dropped at the optimum); "
        << s.optimizations << " optimisations, " << s.optimization_failures << " failed; " << s.nodes_refined
        << " nodes refined at the end in " << s.refine_rounds << " rounds (" << s.nodes_reseated
        << " after a correlative search); "
        << s.stretches_reanchored << " stretches turned back";
  std::cerr << out.str() << "\n";
  if (offered > 10 && s.used * 2 < offered)
    std::cerr << "mrslam_slam_log: WARNING: most scans were rejected (" << s.used << " of " << offered
              << " used): the trajectory and map cover little of the log\n";
  if (s.used > 10 && o.scan_matching && s.matched * 2 < s.used)
    std::cerr << "mrslam_slam_log: WARNING: most scan matches failed (" << s.matched << " of " << s.used
              << "): the trajectory is mostly odometry and the map will be smeared\n";
  else if (o.scan_matching && s.matchesOftenFailed())
    std::cerr << "mrslam_slam_log: WARNING: " << s.used - s.matched << " of " << s.used
              << " scans were not matched to the local map: the track leans on odometry there; check the map\n";
  if (o.scan_matching && s.scansOftenSeeLittle())
    std::cerr << "mrslam_slam_log: WARNING: " << s.few_returns << " of " << s.used
              << " scans had too few returns to correct the predicted motion (a short laser in open space?): the"
              << " map follows the prediction there and may drift; check the map\n";
  if (s.revisitsRarelyConfirmed())
    std::cerr << "mrslam_slam_log: WARNING: the track came back to mapped places " << s.loop_attempts
              << " times and the scans agreed " << s.loop_accepted
              << " times: the map is likely doubled or bent there (a lost track), or the place changed; check the map\n";
  if (s.odometryOftenOverruled())
    std::cerr << "mrslam_slam_log: WARNING: the scans overruled the odometry on " << s.odometryOverruled() << " of "
              << s.used << " scans (slipped, jumped or missed a turn): the log's odometry does not tell this robot's"
              << " motion, or the track is lost; check the map\n";
  if (s.turnsOftenDoubted())
    std::cerr << "mrslam_slam_log: WARNING: on " << s.odometry_turns_doubted << " of " << s.used
              << " scans the scan fitted clearly better turned far from the odometry's heading, too poorly to"
              << " follow it: the odometry may have missed turns there and the map be bent; check the map\n";
  if (s.optimization_failures)
    std::cerr << "mrslam_slam_log: WARNING: " << s.optimization_failures << " pose-graph optimisation(s) failed: "
              << s.last_problem << "\n";
  if (!s.gyro_problem.empty())
    std::cerr << "mrslam_slam_log: WARNING: " << s.gyro_problem << " (" << s.gyro_set_aside << " scans)\n";
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  const std::string problem = parseOptions(argc, argv, o);
  if (argc > 1 && (std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help")) {
    std::cout << kUsage;
    return 0;
  }
  if (!problem.empty()) return fail(problem + "\n" + kUsage);

  slam::RobotSlamParams params;
  try {
    if (!o.config_path.empty()) params = slam::loadRobotSlamParams(o.config_path);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  params.use_scan_matching = params.use_scan_matching && o.scan_matching;
  params.use_imu = o.simulated_imu;
  params.loop_closure = params.loop_closure && o.loop_closure;

  const auto wall_start = std::chrono::steady_clock::now();
  slam::RobotLog log;
  try {
    log = slam::readRobotLog(o.log_path);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  for (const auto& note : log.notes) std::cerr << "note: " << note << "\n";
  for (size_t i = 0; i < log.warnings.size() && i < 20; ++i) std::cerr << "warning: " << log.warnings[i] << "\n";
  if (log.warnings.size() > 20) std::cerr << "warning: ... and " << log.warnings.size() - 20 << " more\n";
  if (!log.warnings.empty() && !o.allow_partial) {
    std::cerr << "mrslam_slam_log: " << o.log_path << ": partial input (" << log.warnings.size()
              << " problem(s) above, " << log.records.size()
              << " scans readable); nothing written. --allow-partial runs on what was read\n";
    return kPartialInput;
  }
  if (o.simulated_imu && !log.records.front().has_reference)
    return fail(o.log_path + ": --simulated-imu needs a log with reference poses (the corrected CARMEN logs)");
  if (const size_t reach = std::max(o.first_scan, o.last_scan); o.scan_window && reach >= log.records.size())
    return fail(o.log_path + ": --scans reaches scan " + std::to_string(reach) + ", but the log has " +
                std::to_string(log.records.size()) + " scans (0 to " + std::to_string(log.records.size() - 1) + ")");
  const slam::TimeStampCheck time = slam::checkTimeStamps(log);
  if (!time.usable) {
    if (o.windowed)
      return fail(o.log_path + ": --window needs usable time stamps, but " + time.reason + "; cut it with --scans instead");
    std::cerr << "mrslam_slam_log: warning: " << o.log_path << ": " << time.reason
              << "; the run follows the order of the lines and no rule uses the time between scans"
              << (o.simulated_imu ? " (the simulated gyro, which needs time, is off)" : "") << "\n";
  }

  const std::unique_ptr<slam::FrontEnd> front_end = slam::makeFrontEnd(params, log.laser_in_base);
  slam::FrontEnd& robot = *front_end;
  robot.setTimeUsable(time.usable);
  if (!log.has_odometry) {
    std::cerr << "mrslam_slam_log: warning: " << o.log_path
              << ": no odometry in the log; each scan's motion is found from the scans alone\n";
    robot.setOdometryAvailable(false);
  }
  slam::SimulatedGyro gyro(slam::GyroNoiseModel{}, o.imu_seed);
  std::vector<UsedScan> used;
  const double log_start = log.records.front().scan.stamp;
  size_t first_in_window = log.records.size(), offered = 0;
  for (size_t k = 0; k < log.records.size(); ++k) {
    const slam::LogRecord& r = log.records[k];
    const double t_log = r.scan.stamp - log_start;
    if (o.outside(k, t_log)) continue;
    if (first_in_window == log.records.size()) {
      first_in_window = k;
      if (r.has_reference && o.cut())  // where this window's map frame sits in the log's frame
        std::cerr << "window starts at scan " << k << ", reference pose " << r.reference.x << " " << r.reference.y << " "
                  << r.reference.yaw << "\n";
    } else {
      robot.addOdometry(r.odometry);
    }
    if (o.simulated_imu && time.usable && k > first_in_window) {
      const double t0 = log.records[k - 1].scan.stamp, t1 = r.scan.stamp;
      const double true_change = mrslam::Pose2D::normalizeAngle(r.reference.yaw - log.records[k - 1].reference.yaw);
      // A gap too long for the gyro to cover (SimulatedGyro::kMaxSamples) gets no gyro increment.
      if (t1 > t0 && (t1 - t0) * slam::GyroNoiseModel{}.rate_hz <= slam::SimulatedGyro::kMaxSamples)
        robot.addGyro(gyro.integratedYaw(t0, t1, true_change), gyro.integratedVariance(t1 - t0));
    }
    ++offered;
    const slam::ScanStep step = robot.processScan(r.scan);
    if (step.used) used.push_back({k, r.scan.stamp});
  }
  if (offered == 0) return fail(o.log_path + ": no scan in the window");
  robot.finish();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();

  // The final estimate of every scan's pose (loop closures move earlier ones).
  std::ofstream trajectory(o.trajectory_path);
  if (!trajectory) return fail(o.trajectory_path + ": cannot write");
  trajectory << std::fixed << std::setprecision(6);
  const std::vector<mrslam::Pose2D> poses = robot.trajectory();
  for (size_t i = 0; i < poses.size() && i < used.size(); ++i)
    trajectory << used[i].stamp << ' ' << poses[i].x << ' ' << poses[i].y << ' ' << poses[i].yaw << ' ' << used[i].index << '\n';
  trajectory.close();
  if (!trajectory) return fail(o.trajectory_path + ": write failed");
  if (!o.map_path.empty()) {
    try {
      mrslam::saveMap(robot.map(), o.map_path, o.png ? ".png" : ".pgm");
    } catch (const std::exception& e) {
      return fail(e.what());
    }
  }
  printSummary(o, robot, log.records.size(), offered);
  if (o.stats) {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    const slam::FrontEndStats s = robot.stats();
    const double duration = used.empty() ? 0 : used.back().stamp - used.front().stamp;
    std::cout << std::fixed << std::setprecision(1) << "scans " << s.used << " matched " << s.matched << " gated "
              << s.gated << " few_returns " << s.few_returns << " odometry_jumps " << s.odometry_jumps
              << " loop_closures " << s.loop_accepted
              << " tracking_s " << s.tracking_ms / 1000 << " loop_search_s " << s.loop_search_ms / 1000
              << " optimization_s " << s.optimization_ms / 1000 << " seconds " << std::setprecision(3) << seconds
              << " scans_per_s " << std::setprecision(1) << s.used / seconds << " log_s " << duration << " x_realtime "
              << duration / seconds << " peak_mb " << usage.ru_maxrss / 1024.0 << "\n";
  }
  return 0;
}
