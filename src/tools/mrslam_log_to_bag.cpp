// mrslam_log_to_bag: turns a real recorded log into a ROS bag for the nodelets.
//
//   mrslam_log_to_bag LOG OUT.bag [--robot NAME:START:END ...] [--start-time T]
//                     [--simulated-imu [--imu-seed N] [--imu-rate HZ]] [--max-scans N]
//                     [--scan-period S] [--allow-partial] [--turned-sensors]
//
// Each --robot takes the scans of the log between START and END seconds after its first scan
// (END 0: to the end) and plays them as robot NAME, all windows shifted to start together at
// T (default 100 s of ROS time), so one long real log yields several robots exploring different
// parts of one building at the same time. Without --robot the whole log is robot1.
// Per robot, in its namespace: NAME/scan (sensor_msgs/LaserScan, frame NAME/laser),
// NAME/odom (nav_msgs/Odometry NAME/odom -> NAME/base_link, the log's raw wheel odometry
// chained), tf NAME/odom -> NAME/base_link and NAME/base_link -> NAME/laser with every scan
// (a log with no odometry at all gets neither NAME/odom nor the odom tf: play it with
// robot.launch odometry:=false; zero motion would claim the robot stood still),
// and with --simulated-imu NAME/imu_simulated (sensor_msgs/Imu, SIMULATED gyro from the
// log's reference trajectory, see simulated_gyro.h; orientation and acceleration marked
// unknown). The log's reference poses, when it has them, go to NAME/reference_pose
// (geometry_msgs/PoseStamped in the log's own world frame, named "reference"; the same frame
// for all robots of one log, which is what the multi-robot ground truth is made from). They
// are for evaluation only; nothing in the stack subscribes to them.
// --turned-sensors writes what the same sensors report when mounted otherwise, to prove that
// the stack reads mountings from tf (sensor_mount.h): the laser upside down (rolled 180 degrees
// about its x axis: its beams sweep the other way, so the ranges come in reverse order), and the
// gyro on its side in frame NAME/imu (its x axis pointing up: the yaw rate is its
// angular_velocity.x), each with its tf from NAME/base_link.
//
// Refusals, each one line and exit 2, nothing left behind: options out of range (--start-time
// and every stamp must fit ROS time, --imu-rate 1..1000 Hz), a window with no scan, a bag that
// cannot be written completely (full disk). A log whose time stamps are unusable (all equal,
// too coarse, not increasing) needs --scan-period S, which spaces the scans S seconds apart in
// the order of the lines. Partial input (lines skipped, a truncated file) exits 3 unless
// --allow-partial. The simulated gyro covers no gap longer than a minute (no samples there).
#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_msgs/TFMessage.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "mrslam/slam/robot_log.h"
#include "mrslam/slam/simulated_gyro.h"
#include "ros_conversions.h"

namespace {

namespace slam = mrslam::slam;
using mrslam::Pose2D;
using mrslam::nodelets::transformMsg;
using mrslam::nodelets::yawToQuaternion;

struct Window {
  std::string robot;
  double start = 0, end = 0;  // seconds after the log's first scan; end 0 = to the end
};

constexpr const char* kUsage =
    "usage: mrslam_log_to_bag LOG OUT.bag [--robot NAME:START:END ...] [--start-time T]\n"
    "                         [--simulated-imu [--imu-seed N] [--imu-rate HZ]] [--max-scans N]\n"
    "                         [--scan-period S] [--allow-partial] [--turned-sensors]\n";
constexpr int kBadInput = 2, kPartialInput = 3;
constexpr double kMaxRosTime = 4294967295.0;  // ros::Time holds unsigned 32-bit seconds
constexpr double kMaxGyroGap = 60.0;           // s: no simulated gyro across a longer gap

int fail(const std::string& message) {
  std::cerr << "mrslam_log_to_bag: " << message << "\n";
  return kBadInput;
}

// A whole number or a finite real from an option's text, or an exception naming the option.
double number(const std::string& option, const std::string& text) {
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (...) {
    used = 0;
  }
  if (used != text.size() || !std::isfinite(v)) throw std::invalid_argument(option + " needs a number, got '" + text + "'");
  return v;
}

struct Options {
  std::string log_path, bag_path;
  std::vector<Window> windows;
  double start_time = 100.0, imu_rate = 100.0, scan_period = 0;
  bool simulated_imu = false, allow_partial = false, turned_sensors = false;
  unsigned imu_seed = 1;
  size_t max_scans = 0;
};

Options parseOptions(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--robot") {
      const std::string spec = next();
      const size_t c1 = spec.find(':'), c2 = spec.find(':', c1 + 1);
      if (c1 == std::string::npos || c2 == std::string::npos) throw std::invalid_argument("--robot expects NAME:START:END, got " + spec);
      Window w{spec.substr(0, c1), number("--robot", spec.substr(c1 + 1, c2 - c1 - 1)), number("--robot", spec.substr(c2 + 1))};
      if (w.robot.empty() || w.start < 0 || (w.end != 0 && w.end <= w.start))
        throw std::invalid_argument("--robot " + spec + ": a name, START >= 0 and END after START (or 0: to the end)");
      o.windows.push_back(w);
    } else if (a == "--start-time") {
      o.start_time = number(a, next());
    } else if (a == "--simulated-imu") {
      o.simulated_imu = true;
    } else if (a == "--imu-seed") {
      o.imu_seed = static_cast<unsigned>(number(a, next()));
    } else if (a == "--imu-rate") {
      o.imu_rate = number(a, next());
    } else if (a == "--max-scans") {
      o.max_scans = static_cast<size_t>(std::max(0.0, number(a, next())));
    } else if (a == "--scan-period") {
      o.scan_period = number(a, next());
    } else if (a == "--allow-partial") {
      o.allow_partial = true;
    } else if (a == "--turned-sensors") {
      o.turned_sensors = true;
    } else if (!a.empty() && a[0] == '-') {
      throw std::invalid_argument("unknown option " + a);
    } else if (o.log_path.empty()) {
      o.log_path = a;
    } else if (o.bag_path.empty()) {
      o.bag_path = a;
    } else {
      throw std::invalid_argument("too many arguments");
    }
  }
  if (o.log_path.empty() || o.bag_path.empty()) throw std::invalid_argument("missing arguments");
  if (!(o.start_time >= 1 && o.start_time < kMaxRosTime)) throw std::invalid_argument("--start-time must lie in 1 .. 4294967295 s (ROS time)");
  if (!(o.imu_rate >= 1 && o.imu_rate <= 1000)) throw std::invalid_argument("--imu-rate must lie in 1 .. 1000 Hz");
  if (o.scan_period < 0 || o.scan_period > 3600) throw std::invalid_argument("--scan-period must lie in 0 .. 3600 s");
  if (o.windows.empty()) o.windows.push_back({"robot1", 0, 0});
  return o;
}

// The scans of one window with the ROS stamp each gets: in increasing order (the few
// backwards-jittering ipc stamps of real logs are nudged forward).
struct Stamped {
  size_t index;
  double stamp;
};
std::vector<Stamped> windowScans(const slam::RobotLog& log, const Window& win, const Options& o, bool time_usable) {
  std::vector<Stamped> out;
  const double log_start = log.records.front().scan.stamp;
  double shift = 0, last = -1;
  for (size_t k = 0; k < log.records.size(); ++k) {
    const double t_log = time_usable ? log.records[k].scan.stamp - log_start : k * o.scan_period;
    if (t_log < win.start || (win.end > 0 && t_log > win.end)) continue;
    if (o.max_scans && out.size() >= o.max_scans) break;
    if (out.empty()) shift = o.start_time - t_log;
    const double t = std::max(t_log + shift, last + 1e-3);
    out.push_back({k, t});
    last = t;
  }
  return out;
}

// --turned-sensors: the laser rolled 180 degrees about its x axis, the gyro's x axis along the
// robot's z axis.
const Eigen::Quaterniond kLaserRoll(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
const Eigen::Quaterniond kGyroOnItsSide(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitY()));

geometry_msgs::TransformStamped mountMsg(const std::string& parent, const std::string& child, const ros::Time& stamp,
                                         double x, double y, const Eigen::Quaterniond& rotation) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.transform.translation.x = x;
  t.transform.translation.y = y;
  t.transform.rotation.w = rotation.w();
  t.transform.rotation.x = rotation.x();
  t.transform.rotation.y = rotation.y();
  t.transform.rotation.z = rotation.z();
  return t;
}

void writeScan(rosbag::Bag& bag, const std::string& ns, const slam::RobotLog& log, size_t k, const Pose2D& odometry,
               const ros::Time& stamp, bool turned) {
  const slam::LogRecord& r = log.records[k];
  sensor_msgs::LaserScan scan;
  scan.header.stamp = stamp;
  scan.header.frame_id = ns + "/laser";
  const double last_angle = r.scan.angle_min + r.scan.angle_increment * (r.scan.ranges.size() - 1);
  scan.angle_increment = static_cast<float>(r.scan.angle_increment);
  scan.range_min = static_cast<float>(r.scan.range_min);
  scan.range_max = static_cast<float>(r.scan.range_max);
  scan.ranges = r.scan.ranges;
  if (turned) {
    // Upside down, the beam the log has at angle a is at -a in the laser's frame: the same
    // sweep direction from -last to -first, the ranges in reverse order.
    scan.angle_min = static_cast<float>(-last_angle);
    scan.angle_max = static_cast<float>(-r.scan.angle_min);
    std::reverse(scan.ranges.begin(), scan.ranges.end());
  } else {
    scan.angle_min = static_cast<float>(r.scan.angle_min);
    scan.angle_max = static_cast<float>(last_angle);
  }
  // Odometry and tf first: a consumer has the motion up to the scan when the scan arrives.
  tf2_msgs::TFMessage tf;
  if (log.has_odometry) {
    nav_msgs::Odometry odom;
    odom.header.stamp = stamp;
    odom.header.frame_id = ns + "/odom";
    odom.child_frame_id = ns + "/base_link";
    odom.pose.pose.position.x = odometry.x;
    odom.pose.pose.position.y = odometry.y;
    odom.pose.pose.orientation = yawToQuaternion(odometry.yaw);
    bag.write("/" + ns + "/odom", stamp, odom);
    tf.transforms.push_back(transformMsg(ns + "/odom", ns + "/base_link", stamp, odometry));
  }
  if (turned) {
    const Eigen::Quaterniond heading(Eigen::AngleAxisd(log.laser_in_base.yaw, Eigen::Vector3d::UnitZ()));
    tf.transforms.push_back(mountMsg(ns + "/base_link", ns + "/laser", stamp, log.laser_in_base.x, log.laser_in_base.y,
                                     heading * kLaserRoll));
    tf.transforms.push_back(mountMsg(ns + "/base_link", ns + "/imu", stamp, 0, 0, kGyroOnItsSide));
  } else {
    tf.transforms.push_back(transformMsg(ns + "/base_link", ns + "/laser", stamp, log.laser_in_base));
  }
  bag.write("/tf", stamp, tf);
  bag.write("/" + ns + "/scan", stamp, scan);
  if (r.has_reference) {
    geometry_msgs::PoseStamped ref;
    ref.header.stamp = stamp;
    ref.header.frame_id = "reference";
    ref.pose.position.x = r.reference.x;
    ref.pose.position.y = r.reference.y;
    ref.pose.orientation = yawToQuaternion(r.reference.yaw);
    bag.write("/" + ns + "/reference_pose", stamp, ref);
  }
}

// The SIMULATED gyro's samples between two scans (none across a gap longer than a minute).
size_t writeGyro(rosbag::Bag& bag, const std::string& ns, slam::SimulatedGyro& gyro, const slam::GyroNoiseModel& model,
                 double t0, double t1, double true_change, bool turned) {
  if (t1 - t0 > kMaxGyroGap) return 0;
  const double rate_variance = std::pow(model.noise_density * M_PI / 180.0, 2) * model.rate_hz;
  // The robot's z axis in the gyro's frame: the turn, and its noise, lie along it.
  const Eigen::Vector3d axis = (turned ? kGyroOnItsSide.conjugate() : Eigen::Quaterniond::Identity()) * Eigen::Vector3d::UnitZ();
  size_t n = 0;
  for (const slam::GyroSample& s : gyro.samples(t0, t1, true_change)) {
    sensor_msgs::Imu imu;
    imu.header.stamp = ros::Time(s.stamp);
    imu.header.frame_id = ns + (turned ? "/imu" : "/base_link");
    imu.orientation_covariance[0] = -1;          // no orientation
    imu.linear_acceleration_covariance[0] = -1;  // no accelerometer
    imu.angular_velocity.x = axis.x() * s.rate;
    imu.angular_velocity.y = axis.y() * s.rate;
    imu.angular_velocity.z = axis.z() * s.rate;
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 3; ++col) imu.angular_velocity_covariance[3 * row + col] = rate_variance * axis(row) * axis(col);
    bag.write("/" + ns + "/imu_simulated", imu.header.stamp, imu);
    ++n;
  }
  return n;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && (std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help")) {
    std::cout << kUsage;
    return 0;
  }
  if (argc < 3) return fail(std::string("missing arguments\n") + kUsage);
  Options o;
  try {
    o = parseOptions(argc, argv);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  slam::RobotLog log;
  try {
    log = slam::readRobotLog(o.log_path);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  for (const auto& note : log.notes) std::cerr << "note: " << note << "\n";
  for (const auto& w : log.warnings) std::cerr << "warning: " << w << "\n";
  if (!log.warnings.empty() && !o.allow_partial) {
    std::cerr << "mrslam_log_to_bag: " << o.log_path << ": partial input (" << log.warnings.size()
              << " problem(s) above); no bag written. --allow-partial converts what was read\n";
    return kPartialInput;
  }
  if (o.simulated_imu && !log.records.front().has_reference) return fail(o.log_path + ": --simulated-imu needs a log with reference poses");
  const slam::TimeStampCheck time = slam::checkTimeStamps(log);
  if (!time.usable && !(o.scan_period > 0))
    return fail(o.log_path + ": " + time.reason + "; give --scan-period S to space the scans S seconds apart in the order of the lines");
  const bool time_usable = time.usable && !(o.scan_period > 0);

  // Everything is checked before the bag is opened: a refusal leaves no file behind.
  std::vector<std::vector<Stamped>> scans;
  for (const Window& win : o.windows) {
    scans.push_back(windowScans(log, win, o, time_usable));
    if (scans.back().empty()) return fail(o.log_path + ": no scan in the window of " + win.robot);
    const double last = scans.back().back().stamp;
    if (!(last < kMaxRosTime))
      return fail(o.log_path + ": scan " + std::to_string(scans.back().back().index) + " would be stamped " +
                  std::to_string(last) + " s, beyond ROS time (the log's time stamps jump too far)");
  }
  const auto odometry = slam::chainOdometry(log);
  // rosbag::Bag's destructor closes the bag, and closing a bag whose writes failed throws from
  // the destructor (std::terminate): after a failure the object is deliberately not destroyed.
  auto bag = std::make_unique<rosbag::Bag>();
  try {
    bag->open(o.bag_path, rosbag::bagmode::Write);
    bag->setCompression(rosbag::compression::LZ4);
    for (size_t w = 0; w < o.windows.size(); ++w) {
      const std::string& ns = o.windows[w].robot;
      slam::GyroNoiseModel model;
      model.rate_hz = o.imu_rate;
      slam::SimulatedGyro gyro(model, o.imu_seed + static_cast<unsigned>(w));
      for (size_t i = 0; i < scans[w].size(); ++i) {
        const size_t k = scans[w][i].index;
        if (o.simulated_imu && i > 0) {
          const double change = Pose2D::normalizeAngle(log.records[k].reference.yaw - log.records[scans[w][i - 1].index].reference.yaw);
          writeGyro(*bag, ns, gyro, model, scans[w][i - 1].stamp, scans[w][i].stamp, change, o.turned_sensors);
        }
        writeScan(*bag, ns, log, k, odometry[k], ros::Time(scans[w][i].stamp), o.turned_sensors);
      }
      std::cout << ns << ": " << scans[w].size() << " scans from " << o.windows[w].start << " s to "
                << (o.windows[w].end > 0 ? std::to_string(o.windows[w].end) + " s" : std::string("the end")) << " of "
                << o.log_path << (log.has_odometry ? "" : " (no odometry: no " + ns + "/odom nor odom tf; play it with robot.launch odometry:=false)")
                << "\n";
    }
    bag->close();
  } catch (const std::exception& e) {
    static rosbag::Bag* abandoned = nullptr;  // see above: never destroyed, yet still referenced
    abandoned = bag.release();
    (void)abandoned;
    std::remove(o.bag_path.c_str());
    return fail(o.bag_path + ": write failed (" + std::string(e.what()).substr(0, 200) + "); nothing kept");
  }
  return 0;
}
