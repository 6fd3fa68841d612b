// Reads FusionParams from a yaml file (config/fusion.yaml documents every key). Keys that
// are absent keep their defaults; unknown keys and bad values are errors, so a typo in a
// parameter name is reported instead of silently ignored.
#pragma once

#include <stdexcept>
#include <string>

#include "mrslam/fusion/map_fusion.h"

namespace mrslam::fusion {

class ParamsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

FusionParams loadFusionParams(const std::string& yaml_path);

}  // namespace mrslam::fusion
