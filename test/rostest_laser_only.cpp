// rostest (test/laser_only.test): robot.launch with odometry:=false on a real laser-only bag (the
// CCNY laser_scan_matcher demo: a Hokuyo carried through rooms, /scan only, no odometry, no tf,
// frame "/laser"). The bag has no reference poses, so the test judges the published poses by the
// scans' agreement with each other (bench/map_consistency.h): every scan cast from its pose into
// one grid, the share of wall hits in cells other beams pass through. The same scans cast all
// from one pose (a robot that believed it stood still) must do far worse, which proves the laser
// moved and that the bound can fail. Also checks: nearly every scan used, the grid published,
// and tf map -> laser following the published pose. Robot name, base frame and the wait are
// the test's parameters (test/laser_only.test passes the launch's). After the bag, this node
// takes the silent scan topic over and sends scans from another laser frame, which must be
// refused and counted, not read as the first laser's.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2/utils.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <map>
#include <mutex>
#include <string>

#include "mrslam/bench/map_consistency.h"
#include "ros_conversions.h"

namespace {

using mrslam::Pose2D;

struct Recorder {
  std::mutex mutex;
  std::map<uint64_t, mrslam::slam::LaserScan> scans;  // by stamp (ns): as the bag played them
  nav_msgs::Path::ConstPtr trajectory;
  nav_msgs::OccupancyGrid::ConstPtr map;
  void onScan(const sensor_msgs::LaserScan::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    scans[m->header.stamp.toNSec()] = mrslam::nodelets::scanFromMsg(*m);
  }
  void onTrajectory(const nav_msgs::Path::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    trajectory = m;
  }
  void onMap(const nav_msgs::OccupancyGrid::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    map = m;
  }
};

TEST(LaserOnly, TracksALaserCarriedThroughRoomsFromItsScansAlone) {
  ros::NodeHandle nh, pnh("~");
  int expected_scans = 0;
  double max_conflict = 0, max_share_of_still = 0, wait_s = 0;
  std::string robot, base_frame;
  pnh.param<std::string>("robot", robot, "ccny");  // robot.launch's namespace and frame prefix
  pnh.param<std::string>("base_frame", base_frame, "laser");
  pnh.param("wait_s", wait_s, 100.0);  // wall time for the bag to play through
  pnh.param("expected_scans", expected_scans, 360);
  pnh.param("max_conflict", max_conflict, 0.2);
  pnh.param("max_share_of_still", max_share_of_still, 0.25);
  Recorder rec;
  const std::string ns = "/" + robot + "/", map_frame = robot + "/map";
  auto scan_sub = nh.subscribe(ns + "scan", 1000, &Recorder::onScan, &rec);
  auto path_sub = nh.subscribe(ns + "trajectory", 1, &Recorder::onTrajectory, &rec);
  auto map_sub = nh.subscribe(ns + "map", 1, &Recorder::onMap, &rec);
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  ros::AsyncSpinner spinner(2);
  spinner.start();

  // Wait (wall time) for the bag to be played through and the last poses to be published.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(wait_s);
  while (ros::WallTime::now() < deadline) {
    ros::WallDuration(0.2).sleep();
    std::lock_guard<std::mutex> lock(rec.mutex);
    if (static_cast<int>(rec.scans.size()) >= expected_scans && rec.trajectory && rec.map &&
        rec.trajectory->poses.size() >= rec.scans.size() * 95 / 100)
      break;
  }
  ros::WallDuration(2.0).sleep();  // the trajectory is republished at most once a second
  std::lock_guard<std::mutex> lock(rec.mutex);
  ASSERT_TRUE(rec.map) << "no grid on " << ns << "map";
  ASSERT_TRUE(rec.trajectory) << "no trajectory on " << ns << "trajectory";
  EXPECT_EQ(rec.map->header.frame_id, map_frame);
  const size_t known = std::count_if(rec.map->data.begin(), rec.map->data.end(), [](int8_t v) { return v >= 0; });
  EXPECT_GT(known, 5000u) << "the map has hardly any known cells";
  EXPECT_GE(static_cast<int>(rec.scans.size()), expected_scans * 95 / 100) << "the bag's scans did not all arrive";
  EXPECT_GE(rec.trajectory->poses.size(), rec.scans.size() * 95 / 100) << "scans were not used";

  std::vector<const mrslam::slam::LaserScan*> scans;
  std::vector<Pose2D> poses, still;
  for (const auto& p : rec.trajectory->poses) {
    const auto scan = rec.scans.find(p.header.stamp.toNSec());
    if (scan == rec.scans.end()) continue;
    scans.push_back(&scan->second);
    poses.push_back(mrslam::nodelets::poseFromMsg(p.pose));
    still.push_back(Pose2D{});
  }
  ASSERT_GT(scans.size(), 100u) << "the trajectory's stamps do not match the bag's scans";
  double travelled = 0;
  for (size_t i = 1; i < poses.size(); ++i) travelled += std::hypot(poses[i].x - poses[i - 1].x, poses[i].y - poses[i - 1].y);
  const auto ours = mrslam::bench::mapConsistency(scans, poses, Pose2D{});
  const auto stood_still = mrslam::bench::mapConsistency(scans, still, Pose2D{});
  std::printf("laser only: %zu poses, %.1f m travelled, conflict %.4f (all scans cast from one pose: %.4f)\n",
              poses.size(), travelled, ours.conflict, stood_still.conflict);
  EXPECT_LT(ours.conflict, max_conflict);
  EXPECT_LT(ours.conflict, max_share_of_still * stood_still.conflict) << "the scans barely agree better than standing still";

  // tf map -> laser is the newest pose (no odometry frame in between).
  std::string error;
  ASSERT_TRUE(buffer.canTransform(map_frame, base_frame, ros::Time(0), &error)) << error;
  const auto t = buffer.lookupTransform(map_frame, base_frame, ros::Time(0)).transform;
  const Pose2D last = mrslam::nodelets::poseFromMsg(rec.trajectory->poses.back().pose);
  EXPECT_NEAR(t.translation.x, last.x, 0.02);
  EXPECT_NEAR(t.translation.y, last.y, 0.02);
  EXPECT_NEAR(Pose2D::normalizeAngle(tf2::getYaw(t.rotation) - last.yaw), 0.0, 0.01);
}

// Runs after the test above: the bag has ended and its scans are all used.
TEST(LaserOnly, RefusesScansFromAnotherLaserFrame) {
  ros::NodeHandle nh, pnh("~");
  std::string robot;
  pnh.param<std::string>("robot", robot, "ccny");
  const std::string ns = "/" + robot + "/";
  std::mutex mutex;
  nav_msgs::Path::ConstPtr trajectory;
  long refused = -1, resets = -1;
  auto path_sub = nh.subscribe<nav_msgs::Path>(ns + "trajectory", 1, [&](const nav_msgs::Path::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    trajectory = m;
  });
  auto diagnostics_sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>("/diagnostics", 100, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& status : m->status)
      for (const auto& kv : status.values)
        if (kv.key == "scans refused from another laser frame") refused = std::stol(kv.value);
        else if (kv.key == "resets (time jumps)") resets = std::stol(kv.value);
  });
  auto scan_pub = nh.advertise<sensor_msgs::LaserScan>(ns + "scan", 10);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  // The scan topic belongs to the bag's player until it has been silent for input_owner_timeout (5 s).
  ros::WallDuration(6.0).sleep();
  ros::Time last;
  size_t poses_before = 0;
  {
    std::lock_guard<std::mutex> lock(mutex);
    ASSERT_TRUE(trajectory && !trajectory->poses.empty()) << "no trajectory (latched) on " << ns << "trajectory";
    last = trajectory->poses.back().header.stamp;
    poses_before = trajectory->poses.size();
  }
  // Well-formed scans from a second laser: after the last one, then 30 s back and advancing
  // again (three such in a row would count as a restarted bag and wipe the map).
  constexpr int kAhead = 5, kBack = 3, kScans = kAhead + kBack;
  for (int k = 1; k <= kScans; ++k) {
    sensor_msgs::LaserScan scan;
    scan.header.stamp = k <= kAhead ? last + ros::Duration(0.1 * k) : last - ros::Duration(30.0 - 0.1 * (k - kAhead));
    scan.header.frame_id = "laser_rear";
    scan.angle_min = -2.0f;
    scan.angle_increment = 0.01f;
    scan.angle_max = scan.angle_min + scan.angle_increment * 399;
    scan.range_min = 0.1f;
    scan.range_max = 30.0f;
    scan.ranges.assign(400, 2.0f);
    scan_pub.publish(scan);
    ros::WallDuration(0.2).sleep();
  }
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(10.0);
  while (ros::WallTime::now() < deadline) {
    ros::WallDuration(0.2).sleep();
    std::lock_guard<std::mutex> lock(mutex);
    if (refused >= kScans) break;
  }
  ros::WallDuration(1.5).sleep();  // a trajectory the scans would have lengthened is republished within a second
  std::lock_guard<std::mutex> lock(mutex);
  std::printf("another laser frame: %ld scans refused, %ld resets\n", refused, resets);
  EXPECT_EQ(resets, 0) << "scans from another laser frame restarted the map";
  EXPECT_EQ(refused, kScans) << "scans from another laser frame were not refused";
  EXPECT_EQ(trajectory->poses.size(), poses_before) << "scans from another laser frame were used, or restarted the map";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_laser_only");
  return RUN_ALL_TESTS();
}
