// mrslam_map_saver TOPIC OUT.yaml [--png] [--timeout S]: waits for one nav_msgs/OccupancyGrid
// on TOPIC and writes it in map_server format (our own writer: map_server is not in Debian).
// Exit 2 with a message when nothing arrives in time or the grid is malformed.
#include <nav_msgs/OccupancyGrid.h>
#include <ros/ros.h>

#include <iostream>

#include "mrslam/map_io.h"
#include "ros_conversions.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "mrslam_map_saver", ros::init_options::AnonymousName);
  std::vector<std::string> args;
  bool png = false;
  double timeout = 10.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--png") png = true;
    else if (a == "--timeout" && i + 1 < argc) timeout = std::atof(argv[++i]);
    else args.push_back(a);
  }
  if (args.size() != 2) {
    std::cerr << "usage: mrslam_map_saver TOPIC OUT.yaml [--png] [--timeout S]\n";
    return 2;
  }
  const auto msg = ros::topic::waitForMessage<nav_msgs::OccupancyGrid>(args[0], ros::Duration(timeout));
  if (!msg) {
    std::cerr << "mrslam_map_saver: no grid on " << args[0] << " within " << timeout << " s\n";
    return 2;
  }
  const std::string problem = mrslam::nodelets::gridMsgProblem(*msg, 400LL * 1000 * 1000);
  if (!problem.empty()) {
    std::cerr << "mrslam_map_saver: " << args[0] << ": " << problem << "\n";
    return 2;
  }
  try {
    mrslam::saveMap(mrslam::nodelets::gridFromMsg(*msg), args[1], png ? ".png" : ".pgm");
  } catch (const std::exception& e) {
    std::cerr << "mrslam_map_saver: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
