// rostest (test/robot_front_end.test): robot.launch on a real Intel excerpt played from a bag
// with --clock. Checks that the grid is published, that robot1/map -> robot1/odom exists, and
// that the filtered poses follow the log's reference poses (published in the bag for
// evaluation only) within a stated bound.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/OccupancyGrid.h>
#include <ros/ros.h>
#include <tf2/utils.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <map>
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
  std::set<std::string> published_addresses, merge_received_addresses;
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
};

TEST(RobotFrontEnd, PublishesMapTfAndTracksTheReference) {
  ros::NodeHandle nh, pnh("~");
  int expected_scans = 0;
  double max_trans = 0.05, max_rot_deg = 1.0;
  pnh.param("expected_scans", expected_scans, 100);
  pnh.param("max_step_translation_error", max_trans, max_trans);
  pnh.param("max_step_rotation_error_deg", max_rot_deg, max_rot_deg);
  Recorder rec;
  auto pose_sub = nh.subscribe("/robot1/pose", 1000, &Recorder::onPose, &rec);
  auto ref_sub = nh.subscribe("/robot1/reference_pose", 1000, &Recorder::onReference, &rec);
  auto map_sub = nh.subscribe("/robot1/map", 1, &Recorder::onMap, &rec);
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

  // Zero copy inside the manager: every grid the merge nodelet received is an object the
  // mapping nodelet published (same address), not a copy.
  ASSERT_FALSE(rec.merge_received_addresses.empty()) << "the merge nodelet reported no map";
  size_t same = 0;
  for (const auto& address : rec.merge_received_addresses) same += rec.published_addresses.count(address);
  std::printf("zero copy: %zu of %zu grids received by the merge nodelet have a published address\n", same,
              rec.merge_received_addresses.size());
  EXPECT_EQ(same, rec.merge_received_addresses.size());
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_robot_front_end");
  return RUN_ALL_TESTS();
}
