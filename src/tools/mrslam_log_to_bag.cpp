// mrslam_log_to_bag: turns a real recorded log into a ROS bag for the nodelets.
//
//   mrslam_log_to_bag LOG OUT.bag [--robot NAME:START:END ...] [--start-time T]
//                     [--simulated-imu [--imu-seed N] [--imu-rate HZ]] [--max-scans N]
//
// Each --robot takes the scans of the log between START and END seconds after its first scan
// (END 0: to the end) and plays them as robot NAME, all windows shifted to start together at
// T (default 100 s of ROS time), so one long real log yields several robots exploring different
// parts of one building at the same time. Without --robot the whole log is robot1.
// Per robot, in its namespace: NAME/scan (sensor_msgs/LaserScan, frame NAME/laser),
// NAME/odom (nav_msgs/Odometry NAME/odom -> NAME/base_link, the log's raw wheel odometry
// chained), tf NAME/odom -> NAME/base_link and NAME/base_link -> NAME/laser with every scan,
// and with --simulated-imu NAME/imu_simulated (sensor_msgs/Imu, SIMULATED gyro from the
// log's reference trajectory, see simulated_gyro.h; orientation and acceleration marked
// unknown). The log's reference poses, when it has them, go to NAME/reference_pose
// (geometry_msgs/PoseStamped in the log's own world frame, named "reference"; the same frame
// for all robots of one log, which is what the multi-robot ground truth is made from). They
// are for evaluation only; nothing in the stack subscribes to them.
#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_msgs/TFMessage.h>

#include <iostream>
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
    "                         [--simulated-imu [--imu-seed N] [--imu-rate HZ]] [--max-scans N]\n";

int fail(const std::string& message) {
  std::cerr << "mrslam_log_to_bag: " << message << "\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string log_path, bag_path;
  std::vector<Window> windows;
  double start_time = 100.0, imu_rate = 100.0;
  bool simulated_imu = false;
  unsigned imu_seed = 1;
  size_t max_scans = 0;
  try {
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
        windows.push_back({spec.substr(0, c1), std::stod(spec.substr(c1 + 1, c2 - c1 - 1)), std::stod(spec.substr(c2 + 1))});
      } else if (a == "--start-time") start_time = std::stod(next());
      else if (a == "--simulated-imu") simulated_imu = true;
      else if (a == "--imu-seed") imu_seed = static_cast<unsigned>(std::stoul(next()));
      else if (a == "--imu-rate") imu_rate = std::stod(next());
      else if (a == "--max-scans") max_scans = std::stoul(next());
      else if (a == "-h" || a == "--help") { std::cout << kUsage; return 0; }
      else if (!a.empty() && a[0] == '-') throw std::invalid_argument("unknown option " + a);
      else if (log_path.empty()) log_path = a;
      else if (bag_path.empty()) bag_path = a;
      else throw std::invalid_argument("too many arguments");
    }
  } catch (const std::exception& e) {
    return fail(std::string(e.what()) + "\n" + kUsage);
  }
  if (log_path.empty() || bag_path.empty()) return fail(std::string("missing arguments\n") + kUsage);
  if (!(start_time > 0) || !(imu_rate > 0)) return fail("--start-time and --imu-rate must be positive");
  if (windows.empty()) windows.push_back({"robot1", 0, 0});

  slam::RobotLog log;
  try {
    log = slam::readRobotLog(log_path);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  for (const auto& w : log.warnings) std::cerr << "warning: " << w << "\n";
  const bool has_reference = log.records.front().has_reference;
  if (simulated_imu && !has_reference) return fail(log_path + ": --simulated-imu needs a log with reference poses");

  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Write);
    bag.setCompression(rosbag::compression::LZ4);
  } catch (const std::exception& e) {
    return fail(bag_path + ": cannot write (" + e.what() + ")");
  }
  const double log_start = log.records.front().scan.stamp;
  const auto odometry = slam::chainOdometry(log);
  for (size_t w = 0; w < windows.size(); ++w) {
    const Window& win = windows[w];
    const std::string ns = win.robot;
    slam::GyroNoiseModel model;
    model.rate_hz = imu_rate;
    slam::SimulatedGyro gyro(model, imu_seed + static_cast<unsigned>(w));
    double shift = 0;
    bool first = true;
    size_t written = 0;
    double last_stamp = -1;
    for (size_t k = 0; k < log.records.size(); ++k) {
      const slam::LogRecord& r = log.records[k];
      const double t_log = r.scan.stamp - log_start;
      if (t_log < win.start || (win.end > 0 && t_log > win.end)) continue;
      if (max_scans && written >= max_scans) break;
      if (first) shift = start_time - r.scan.stamp, first = false;
      // Bags need increasing time: the few backwards-jittering ipc stamps are nudged forward.
      const double t = std::max(r.scan.stamp + shift, last_stamp + 1e-3);
      if (simulated_imu && last_stamp > 0) {
        const double change = Pose2D::normalizeAngle(r.reference.yaw - log.records[k - 1].reference.yaw);
        const double rate_variance = std::pow(model.noise_density * M_PI / 180.0, 2) * model.rate_hz;
        for (const slam::GyroSample& s : gyro.samples(last_stamp, t, change)) {
          sensor_msgs::Imu imu;
          imu.header.stamp = ros::Time(s.stamp);
          imu.header.frame_id = ns + "/base_link";
          imu.orientation_covariance[0] = -1;          // no orientation
          imu.linear_acceleration_covariance[0] = -1;  // no accelerometer
          imu.angular_velocity.z = s.rate;
          imu.angular_velocity_covariance[8] = rate_variance;
          bag.write("/" + ns + "/imu_simulated", imu.header.stamp, imu);
        }
      }
      const ros::Time stamp(t);
      sensor_msgs::LaserScan scan;
      scan.header.stamp = stamp;
      scan.header.frame_id = ns + "/laser";
      scan.angle_min = static_cast<float>(r.scan.angle_min);
      scan.angle_increment = static_cast<float>(r.scan.angle_increment);
      scan.angle_max = static_cast<float>(r.scan.angle_min + r.scan.angle_increment * (r.scan.ranges.size() - 1));
      scan.range_min = static_cast<float>(r.scan.range_min);
      scan.range_max = static_cast<float>(r.scan.range_max);
      scan.ranges = r.scan.ranges;
      nav_msgs::Odometry odom;
      odom.header.stamp = stamp;
      odom.header.frame_id = ns + "/odom";
      odom.child_frame_id = ns + "/base_link";
      odom.pose.pose.position.x = odometry[k].x;
      odom.pose.pose.position.y = odometry[k].y;
      odom.pose.pose.orientation = yawToQuaternion(odometry[k].yaw);
      tf2_msgs::TFMessage tf;
      tf.transforms.push_back(transformMsg(ns + "/odom", ns + "/base_link", stamp, odometry[k]));
      tf.transforms.push_back(transformMsg(ns + "/base_link", ns + "/laser", stamp, log.laser_in_base));
      // Odometry and tf first: a consumer has the motion up to the scan when the scan arrives.
      bag.write("/" + ns + "/odom", stamp, odom);
      bag.write("/tf", stamp, tf);
      bag.write("/" + ns + "/scan", stamp, scan);
      if (has_reference) {
        geometry_msgs::PoseStamped ref;
        ref.header.stamp = stamp;
        ref.header.frame_id = "reference";
        ref.pose.position.x = r.reference.x;
        ref.pose.position.y = r.reference.y;
        ref.pose.orientation = yawToQuaternion(r.reference.yaw);
        bag.write("/" + ns + "/reference_pose", stamp, ref);
      }
      last_stamp = t;
      ++written;
    }
    std::cout << ns << ": " << written << " scans from " << win.start << " s to "
              << (win.end > 0 ? std::to_string(win.end) + " s" : std::string("the end")) << " of " << log_path << "\n";
    if (written == 0) std::cerr << "warning: " << ns << ": no scan in the window\n";
  }
  bag.close();
  return 0;
}
