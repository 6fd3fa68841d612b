// Reads FusionParams from a yaml file. config/fusion.yaml lists and documents every key with
// its default, and a test holds it equal to FusionParams{} key by key (the defaults in the
// headers only mirror it). Keys that are absent keep their defaults; unknown keys, values of
// the wrong type and values out of range are errors naming the file and key, so a typo in a
// parameter is reported instead of silently ignored.
#pragma once

#include <map>
#include <stdexcept>
#include <string>

#include "mrslam/fusion/map_fusion.h"

namespace mrslam::fusion {

class ParamsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

FusionParams loadFusionParams(const std::string& yaml_path);

// Every key of the yaml with its value in `params`, written as loadFusionParams reads it.
std::map<std::string, std::string> fusionParamValues(const FusionParams& params);

}  // namespace mrslam::fusion
