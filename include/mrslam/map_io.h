// map_server-compatible map files: a yaml description plus a pgm or png image.
//
// Reading honours every field map_server honours: image (relative to the yaml file),
// resolution, origin [x, y, yaw], negate, occupied_thresh, free_thresh and mode
// (trinary | scale | raw). Writing produces what map_saver writes (trinary pgm or png:
// 0 = occupied, 254 = free, 205 = unknown), so our maps load in any ROS tool.
#pragma once

#include <stdexcept>
#include <string>

#include "mrslam/grid.h"

namespace mrslam {

// Every failure of reading or writing a map: the message names the file and the problem.
class MapIoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Loads a map_server yaml (and the image it names). Throws MapIoError.
OccupancyGrid loadMap(const std::string& yaml_path);

// Writes `yaml_path` and an image beside it with the same stem (".pgm" unless
// `image_extension` is ".png"). Throws MapIoError.
void saveMap(const OccupancyGrid& grid, const std::string& yaml_path,
             const std::string& image_extension = ".pgm");

}  // namespace mrslam
