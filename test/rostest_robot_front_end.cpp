// rostest (test/robot_front_end.test): robot.launch on a real Intel excerpt played from a bag
// with --clock. Checks that the grid is published, that robot1/map -> robot1/odom exists, and
// that the filtered poses follow the log's reference poses (published in the bag for
// evaluation only) within a stated bound. With gyro_delay > 0 (robot_front_end_lagging_gyro.test)
// this node relays the bag's simulated gyro that many wall seconds late, as a loaded host
// delivers it, and checks that the scans waited for it and the map still holds; with
// gyro_without_rate (robot_front_end_rateless_imu.test) it relays the samples as an IMU without
// angular velocity sends them and checks they are set aside. After the bag it
// ends the run (~finish_run) and checks that the map and trajectory come again, no worse.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <std_srvs/Trigger.h>
#include <tf2/utils.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <sstream>

#include "mrslam/bench/trajectory_metrics.h"

namespace {

using mrslam::Pose2D;

Pose2D toPose(const geometry_msgs::Pose& p) { return {p.position.x, p.position.y, tf2::getYaw(p.orientation)}; }

struct Recorder {
  std::mutex mutex;
  std::map<uint64_t, Pose2D> estimate, reference;  // by stamp (ns)
  nav_msgs::OccupancyGrid::ConstPtr map;
  nav_msgs::Path::ConstPtr path;
  std::set<std::string> published_addresses, merge_received_addresses;
  long scans_waited_for_gyro = -1, scans_gyro_did_not_cover = -1;  // the SLAM nodelet's last report
  long imu_samples_without_rate = -1, scans_gyro_set_aside = -1;
  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& status : m->status)
      for (const auto& kv : status.values) {
        if (kv.key == "recent map addresses") {
          std::istringstream in(kv.value);
          std::string a;
          while (in >> a) published_addresses.insert(a);
        }
        if (kv.key == "own map address" && kv.value != "0") merge_received_addresses.insert(kv.value);
        if (kv.key == "scans that waited for the gyro") scans_waited_for_gyro = std::stol(kv.value);
        if (kv.key == "scans the gyro did not cover") scans_gyro_did_not_cover = std::stol(kv.value);
        if (kv.key == "imu samples without angular velocity") imu_samples_without_rate = std::stol(kv.value);
        if (kv.key == "scans whose gyro turn was set aside") scans_gyro_set_aside = std::stol(kv.value);
      }
  }
  void onPose(const geometry_msgs::PoseWithCovarianceStamped::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    estimate[m->header.stamp.toNSec()] = toPose(m->pose.pose);
  }
  void onReference(const geometry_msgs::PoseStamped::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    reference[m->header.stamp.toNSec()] = toPose(m->pose);
  }
  void onMap(const nav_msgs::OccupancyGrid::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    map = m;
  }
  void onPath(const nav_msgs::Path::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    path = m;
  }
  // The global error (500 seeded random pairs) of a published trajectory, against the reference
  // poses of the same stamps (mutex held).
  double globalError(const nav_msgs::Path& trajectory) const {
    std::vector<Pose2D> estimate, matched;
    for (const auto& p : trajectory.poses) {
      const auto ref = reference.find(p.header.stamp.toNSec());
      if (ref == reference.end()) continue;
      estimate.push_back(toPose(p.pose));
      matched.push_back(ref->second);
    }
    if (estimate.size() < 20) return 1e9;
    return mrslam::bench::relationError(estimate, matched, mrslam::bench::randomPairs(estimate.size(), 500, 1)).trans_mean;
  }
};

// The run is over: ~finish_run searches the last submap, refines every node against all the
// others (pose_refinement.h) and publishes the map and the trajectory again.
void checkFinishRun(Recorder& rec, double max_global) {
  nav_msgs::OccupancyGrid::ConstPtr map_before;
  nav_msgs::Path::ConstPtr path_before;
  {
    std::lock_guard<std::mutex> lock(rec.mutex);
    map_before = rec.map;
    path_before = rec.path;
  }
  ASSERT_TRUE(path_before) << "no trajectory on /robot1/trajectory";
  const std::string service = "/robot1/slam/finish_run";
  ASSERT_TRUE(ros::service::waitForService(service, ros::Duration(10.0))) << service;
  std_srvs::Trigger finish;
  ASSERT_TRUE(ros::service::call(service, finish));
  std::printf("%s: %s\n", service.c_str(), finish.response.message.c_str());
  EXPECT_TRUE(finish.response.success) << finish.response.message;
  EXPECT_NE(finish.response.message.find("nodes refined"), std::string::npos);
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(10.0);
  while (ros::WallTime::now() < deadline) {
    ros::WallDuration(0.1).sleep();
    std::lock_guard<std::mutex> lock(rec.mutex);
    if (rec.map != map_before && rec.path != path_before) break;
  }
  std::lock_guard<std::mutex> lock(rec.mutex);
  EXPECT_NE(rec.map, map_before) << "no map published after finish_run";
  ASSERT_NE(rec.path, path_before) << "no trajectory published after finish_run";
  const double before = rec.globalError(*path_before), after = rec.globalError(*rec.path);
  std::printf("finish_run: global error of the published trajectory %.3f m before, %.3f m after\n", before, after);
  EXPECT_LT(after, max_global);
  EXPECT_LT(after, before + 0.02) << "finishing the run made the map worse";
}

// Republishes gyro samples `delay` wall seconds after they arrived; `without_rate`: as an IMU
// that measures no angular velocity sends them (zeros, angular_velocity_covariance[0] = -1, the
// sensor_msgs/Imu convention for "no estimate"); `scale`: times this (-1: a gyro whose sign is
// wrong, 57.3: one that reports degrees per second).
class LateGyro {
 public:
  LateGyro(ros::NodeHandle& nh, double delay, bool without_rate, double scale)
      : delay_(delay),
        without_rate_(without_rate),
        scale_(scale),
        pub_(nh.advertise<sensor_msgs::Imu>("/robot1/imu_late", 2000)),
        sub_(nh.subscribe("/robot1/imu_simulated", 2000, &LateGyro::onImu, this)),
        timer_(nh.createWallTimer(ros::WallDuration(0.002), &LateGyro::release, this)) {}

 private:
  void onImu(const sensor_msgs::Imu::ConstPtr& m) {
    sensor_msgs::Imu::ConstPtr sample = m;
    if (scale_ != 1.0) {
      auto scaled = boost::make_shared<sensor_msgs::Imu>(*m);
      scaled->angular_velocity.x *= scale_;
      scaled->angular_velocity.y *= scale_;
      scaled->angular_velocity.z *= scale_;
      sample = scaled;
    }
    if (without_rate_) {
      auto rateless = boost::make_shared<sensor_msgs::Imu>(*sample);
      rateless->angular_velocity = geometry_msgs::Vector3();
      rateless->angular_velocity_covariance = {-1, 0, 0, 0, 0, 0, 0, 0, 0};
      sample = rateless;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    held_.push_back({ros::WallTime::now() + ros::WallDuration(delay_), sample});
  }
  void release(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    while (!held_.empty() && held_.front().first <= ros::WallTime::now()) {
      pub_.publish(held_.front().second);
      held_.pop_front();
    }
  }
  double delay_;
  bool without_rate_;
  double scale_;
  std::mutex mutex_;
  std::deque<std::pair<ros::WallTime, sensor_msgs::Imu::ConstPtr>> held_;
  ros::Publisher pub_;
  ros::Subscriber sub_;
  ros::WallTimer timer_;
};

TEST(RobotFrontEnd, PublishesMapTfAndTracksTheReference) {
  ros::NodeHandle nh, pnh("~");
  int expected_scans = 0;
  double max_trans = 0.05, max_rot_deg = 1.0, max_global = 1.0, gyro_delay = 0.0;
  pnh.param("expected_scans", expected_scans, 100);
  pnh.param("max_step_translation_error", max_trans, max_trans);
  pnh.param("max_step_rotation_error_deg", max_rot_deg, max_rot_deg);
  pnh.param("max_global_error", max_global, max_global);
  pnh.param("gyro_delay", gyro_delay, gyro_delay);
  bool gyro_without_rate = false;
  pnh.param("gyro_without_rate", gyro_without_rate, gyro_without_rate);
  double gyro_scale = 1.0;
  pnh.param("gyro_scale", gyro_scale, gyro_scale);
  std::unique_ptr<LateGyro> late_gyro;
  if (gyro_delay > 0 || gyro_without_rate || gyro_scale != 1.0)
    late_gyro = std::make_unique<LateGyro>(nh, gyro_delay, gyro_without_rate, gyro_scale);
  Recorder rec;
  auto pose_sub = nh.subscribe("/robot1/pose", 1000, &Recorder::onPose, &rec);
  auto ref_sub = nh.subscribe("/robot1/reference_pose", 1000, &Recorder::onReference, &rec);
  auto map_sub = nh.subscribe("/robot1/map", 1, &Recorder::onMap, &rec);
  auto path_sub = nh.subscribe("/robot1/trajectory", 1, &Recorder::onPath, &rec);
  auto diagnostics_sub = nh.subscribe("/diagnostics", 100, &Recorder::onDiagnostics, &rec);
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  ros::AsyncSpinner spinner(2);
  spinner.start();

  // Wait (wall time) for the bag to be played through.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(100.0);
  bool map_to_odom = false;
  while (ros::WallTime::now() < deadline) {
    ros::WallDuration(0.2).sleep();
    map_to_odom = map_to_odom || buffer.canTransform("robot1/map", "robot1/odom", ros::Time(0));
    std::lock_guard<std::mutex> lock(rec.mutex);
    if (static_cast<int>(rec.estimate.size()) >= expected_scans && rec.map) break;
  }
  ros::WallDuration(2.5).sleep();  // diagnostics (1 Hz) report the last grids
  {
    std::lock_guard<std::mutex> lock(rec.mutex);
    ASSERT_TRUE(rec.map) << "no grid on /robot1/map";
    EXPECT_EQ(rec.map->header.frame_id, "robot1/map");
    EXPECT_EQ(rec.map->data.size(), static_cast<size_t>(rec.map->info.width) * rec.map->info.height);
    const size_t known = std::count_if(rec.map->data.begin(), rec.map->data.end(), [](int8_t v) { return v >= 0; });
    EXPECT_GT(known, 10000u) << "the map has hardly any known cells";
    EXPECT_TRUE(map_to_odom) << "no robot1/map -> robot1/odom transform";
    EXPECT_GE(static_cast<int>(rec.estimate.size()), expected_scans * 9 / 10) << "poses missing";

    std::vector<Pose2D> estimate, reference;
    for (const auto& [stamp, pose] : rec.estimate) {
      const auto ref = rec.reference.find(stamp);
      if (ref == rec.reference.end()) continue;
      estimate.push_back(pose);
      reference.push_back(ref->second);
    }
    ASSERT_GT(estimate.size(), 20u);
    const auto step = mrslam::bench::relationError(estimate, reference, mrslam::bench::consecutivePairs(estimate.size(), 1));
    std::printf("excerpt: %zu poses, scan-to-scan error %.3f m, %.2f deg\n", estimate.size(), step.trans_mean,
                step.rot_mean * 180 / M_PI);
    EXPECT_LT(step.trans_mean, max_trans);
    EXPECT_LT(step.rot_mean * 180 / M_PI, max_rot_deg);
    // Over the whole excerpt (500 seeded random pairs, as scripts/bench_slam's global figure): a
    // turn integrated wrongly once bends everything after it, which the steps barely show.
    const auto global = mrslam::bench::relationError(estimate, reference, mrslam::bench::randomPairs(estimate.size(), 500, 1));
    std::printf("excerpt: global error %.3f m, %.2f deg\n", global.trans_mean, global.rot_mean * 180 / M_PI);
    EXPECT_LT(global.trans_mean, max_global);
    if (gyro_without_rate) {
      // Read as a yaw rate, those zeros would say the robot never turns.
      std::printf("IMU without angular velocity: %ld samples set aside\n", rec.imu_samples_without_rate);
      EXPECT_GT(rec.imu_samples_without_rate, 1000) << "the IMU's samples without angular velocity were not set aside";
    }
    if (gyro_scale != 1.0) {
      std::printf("gyro times %.1f: its turns set aside on %ld scans\n", gyro_scale, rec.scans_gyro_set_aside);
      EXPECT_GT(rec.scans_gyro_set_aside, expected_scans / 2) << "the wrong gyro was not set aside";
    } else if (!gyro_without_rate) {
      EXPECT_EQ(rec.scans_gyro_set_aside, 0) << "a working gyro was set aside";
    }
    if (gyro_delay > 0 && !gyro_without_rate) {
      std::printf("gyro %.2f s late: %ld scans waited for it, %ld it did not cover\n", gyro_delay,
                  rec.scans_waited_for_gyro, rec.scans_gyro_did_not_cover);
      EXPECT_GT(rec.scans_waited_for_gyro, expected_scans / 2) << "scans did not wait for the late gyro";
      // Without the wait every interval would end past the newest sample (2 s of the bag's clock)
      // and go without the gyro. A loaded CI host still leaves a few without it (one full run: 2
      // of 122), where samples of this 1000-a-second stream were lost or a scan waited out
      // imu_wait; those scans go without the gyro, as they should, and the map holds (above).
      EXPECT_GE(rec.scans_gyro_did_not_cover, 0);
      EXPECT_LT(rec.scans_gyro_did_not_cover, expected_scans / 10) << "a gyro late by less than imu_wait left scans without it";
    }

    // Zero copy inside the manager: every grid the merge nodelet received is an object the
    // mapping nodelet published (same address), not a copy.
    ASSERT_FALSE(rec.merge_received_addresses.empty()) << "the merge nodelet reported no map";
    size_t same = 0;
    for (const auto& address : rec.merge_received_addresses) same += rec.published_addresses.count(address);
    std::printf("zero copy: %zu of %zu grids received by the merge nodelet have a published address\n", same,
                rec.merge_received_addresses.size());
    EXPECT_EQ(same, rec.merge_received_addresses.size());
  }
  checkFinishRun(rec, max_global);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_robot_front_end");
  return RUN_ALL_TESTS();
}
