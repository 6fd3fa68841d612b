// mrslam_window_map: the map one robot would build from a time window of a real CARMEN log.
//
//   mrslam_window_map LOG FIRST LAST X Y YAW_DEG OUT.yaml [--seed N]
//
// Ray-casts scans [FIRST, LAST) along the log's reference poses, with a small random-walk
// drift, in a map frame whose pose in the log's frame is (X, Y, YAW_DEG). Used by the demo
// to make several "robots" of one building with known relative frames.
#include <cstdlib>
#include <iostream>
#include <string>

#include "mrslam/bench/pair_maker.h"
#include "mrslam/map_io.h"

int main(int argc, char** argv) {
  if (argc != 8 && argc != 10) {
    std::cerr << "usage: mrslam_window_map LOG FIRST LAST X Y YAW_DEG OUT.yaml [--seed N]\n";
    return 2;
  }
  try {
    const auto scans = mrslam::bench::readCarmenScans(argv[1]);
    const long first = std::stol(argv[2]), last = std::stol(argv[3]);
    if (first < 0 || last <= first || last > static_cast<long>(scans.size())) {
      std::cerr << "mrslam_window_map: " << argv[1] << ": scan window [" << first << ", " << last
                << ") outside the log's " << scans.size() << " scans\n";
      return 2;
    }
    const mrslam::Pose2D frame{std::stod(argv[4]), std::stod(argv[5]), std::stod(argv[6]) * M_PI / 180.0};
    std::mt19937 rng(argc == 10 ? std::stoul(argv[9]) : 1u);
    mrslam::saveMap(mrslam::bench::raycastMap(scans, first, last, frame, mrslam::bench::RaycastParams{}, rng),
                    argv[7], ".png");
  } catch (const std::exception& e) {
    std::cerr << "mrslam_window_map: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
