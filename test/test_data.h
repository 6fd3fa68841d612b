// Paths to the real recorded data beside the repository (../shared/data), for the tests.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace mrslam::test {

inline std::string dataPath(const std::string& relative) {
  return std::string(MRSLAM_DATA_DIR) + "/" + relative;
}
inline std::string referenceMap(const std::string& name) { return dataPath("maps/reference/" + name + ".yaml"); }
inline std::string robotMap(const std::string& name) { return dataPath("maps/robot_built/" + name + ".yaml"); }

struct RunResult {
  int status;          // exit code, -1 when the program did not exit normally (crash)
  std::string output;  // stdout and stderr
};

// Runs a shell command line and collects its exit code and output.
inline RunResult runCommand(const std::string& command_line) {
  FILE* pipe = popen((command_line + " 2>&1").c_str(), "r");
  std::string out;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof(buf), pipe)) out.append(buf, n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

}  // namespace mrslam::test
