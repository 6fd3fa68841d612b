// Paths to the real recorded data beside the repository (../shared/data), for the tests.
#pragma once

#include <string>

namespace mrslam::test {

inline std::string dataPath(const std::string& relative) {
  return std::string(MRSLAM_DATA_DIR) + "/" + relative;
}
inline std::string referenceMap(const std::string& name) { return dataPath("maps/reference/" + name + ".yaml"); }
inline std::string robotMap(const std::string& name) { return dataPath("maps/robot_built/" + name + ".yaml"); }

}  // namespace mrslam::test
