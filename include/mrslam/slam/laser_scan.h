// One planar laser scan as every part of the front end sees it, whatever it came from
// (CARMEN FLASER line, Mines line, MRPT rawlog, sensor_msgs/LaserScan).
#pragma once

#include <cstddef>
#include <vector>

#include "mrslam/grid.h"

namespace mrslam::slam {

struct LaserScan {
  double stamp = 0.0;           // seconds
  double angle_min = 0.0;       // radians, angle of ranges[0] in the laser frame
  double angle_increment = 0.0; // radians between consecutive beams
  double range_min = 0.0;       // metres: shorter readings are not returns
  double range_max = 0.0;       // metres: readings at or beyond this are "no return"
  std::vector<float> ranges;
};

// Why a scan cannot be used at all (empty string when it can). Individual bad beams
// (NaN, inf, out of range) are not a reason: they are skipped by validBeams().
std::string scanProblem(const LaserScan& scan);

// A reading is a return when finite and within [range_min, range_max), and "no return" (the beam
// met nothing up to the sensor's maximum) when at or beyond range_max, compared in the ranges'
// own single precision.
bool isReturn(const LaserScan& scan, float r);
bool isNoReturn(const LaserScan& scan, float r);

// Number of beams that are real returns: finite and within [range_min, range_max).
size_t validBeams(const LaserScan& scan);

// The returns as points (x, y) in the frame of `sensor_pose` (e.g. the laser's pose in
// base_link, or the robot's pose in the map composed with it).
std::vector<std::pair<float, float>> scanPoints(const LaserScan& scan, const Pose2D& sensor_pose);

}  // namespace mrslam::slam
