// mrslam_map_saver TOPIC OUT.yaml [--png] [--timeout S]: waits for one nav_msgs/OccupancyGrid
// on TOPIC and writes it in map_server format (our own writer: map_server is not in Debian).
// The wait runs on the wall clock (a bag's /clock may be stopped or absent while use_sim_time
// is set). Exit 2 with one line when the options are bad, nothing arrives in time, the grid is
// malformed or the files cannot be written.
#include <nav_msgs/OccupancyGrid.h>
#include <ros/master.h>
#include <ros/ros.h>

#include <cmath>
#include <iostream>
#include <mutex>

#include "mrslam/map_io.h"
#include "ros_conversions.h"

namespace {
int fail(const std::string& message) {
  std::cerr << "mrslam_map_saver: " << message << "\n";
  return 2;
}
}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "mrslam_map_saver", ros::init_options::AnonymousName);
  std::vector<std::string> args;
  bool png = false;
  double timeout = 10.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--png") {
      png = true;
    } else if (a == "--timeout") {
      if (i + 1 >= argc) return fail("--timeout needs a number of seconds");
      const std::string text = argv[++i];
      size_t used = 0;
      try {
        timeout = std::stod(text, &used);
      } catch (...) {
        used = 0;
      }
      if (used != text.size() || !(timeout > 0 && timeout <= 86400))
        return fail("--timeout needs seconds in (0, 86400], got '" + text + "'");
    } else {
      args.push_back(a);
    }
  }
  if (args.size() != 2) return fail("usage: mrslam_map_saver TOPIC OUT.yaml [--png] [--timeout S]");
  if (!ros::master::check()) return fail("no ROS master at " + ros::master::getURI());
  ros::NodeHandle nh;
  std::mutex mutex;
  nav_msgs::OccupancyGrid::ConstPtr msg;
  const ros::Subscriber sub = nh.subscribe<nav_msgs::OccupancyGrid>(args[0], 1, [&](const nav_msgs::OccupancyGrid::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    msg = m;
  });
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout);
  while (ros::ok() && ros::WallTime::now() < deadline) {
    ros::spinOnce();
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (msg) break;
    }
    ros::WallDuration(0.02).sleep();
  }
  if (!msg) return fail("no grid on " + args[0] + " within " + std::to_string(static_cast<int>(std::ceil(timeout))) + " s (wall clock)");
  const std::string problem = mrslam::nodelets::gridMsgProblem(*msg, 400LL * 1000 * 1000);
  if (!problem.empty()) return fail(args[0] + ": " + problem);
  try {
    mrslam::saveMap(mrslam::nodelets::gridFromMsg(*msg), args[1], png ? ".png" : ".pgm");
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  return 0;
}
