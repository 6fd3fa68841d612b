// libFuzzer target: the CARMEN and Mines readers (ours), chosen by the first byte, on the rest
// of the input written to a file. Contract: records with scans that pass scanProblem or carry
// their problem in warnings, or a LogError; never a crash or a hang.
//
// The MRPT rawlog reader is MRPT's deserialiser: fuzzed, it allocates whatever element counts a
// rawlog claims before reading them (eight bytes asked for gigabytes of CActionCollection
// entries). That is MRPT's to fix; rawlogs come from the user's own disk, never from a peer.
#include <cstdint>
#include <fstream>
#include <string>

#include "mrslam/slam/robot_log.h"
#include "scratch_dir.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* kExtensions[] = {".log", ".dat"};
  const std::string path = fuzzScratchDir() + "/input" + kExtensions[data[0] % 2];
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
  try {
    const mrslam::slam::RobotLog log = mrslam::slam::readRobotLog(path);
    for (const auto& r : log.records) (void)mrslam::slam::validBeams(r.scan);
    (void)mrslam::slam::checkTimeStamps(log);
    (void)mrslam::slam::chainOdometry(log);
  } catch (const mrslam::slam::LogError&) {
  }
  return 0;
}
