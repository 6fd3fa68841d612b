// libFuzzer target: the map_server map loader (yaml + PGM/PNG image). The input is split at the
// first NUL byte into the yaml text and the image bytes; both are written to files and loaded.
// Contract: either a grid that passes validateGrid or a MapIoError naming a file.
#include <cstdint>
#include <fstream>
#include <string>

#include "mrslam/map_io.h"
#include "scratch_dir.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  const size_t cut = bytes.find('\0');
  const std::string yaml = bytes.substr(0, cut), image = cut == std::string::npos ? "" : bytes.substr(cut + 1);
  const bool png = image.size() >= 4 && image.compare(1, 3, "PNG") == 0;
  const std::string image_name = png ? "m.png" : "m.pgm";
  std::ofstream(fuzzScratchDir() + "/" + image_name, std::ios::binary) << image;
  // The yaml names whatever image it likes; a fuzzed name is fine (missing files are refused).
  std::ofstream(fuzzScratchDir() + "/m.yaml", std::ios::binary) << yaml;
  try {
    const mrslam::OccupancyGrid grid = mrslam::loadMap(fuzzScratchDir() + "/m.yaml");
    if (!mrslam::validateGrid(grid).empty()) __builtin_trap();  // loaded grids are valid
  } catch (const mrslam::MapIoError&) {
  }
  return 0;
}
