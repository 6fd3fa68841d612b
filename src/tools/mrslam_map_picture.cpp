// mrslam_map_picture MAP.yaml OUT.png [MAX_SIDE]: a small picture of a map for the docs:
// unknown borders trimmed, occupancy as grey (white free, black occupied, grey unknown),
// scaled down by area averaging so the longest side is at most MAX_SIDE pixels (default 400).
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mrslam/bench/pair_maker.h"
#include "mrslam/map_io.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: mrslam_map_picture MAP.yaml OUT.png [MAX_SIDE]\n";
    return 2;
  }
  try {
    const mrslam::OccupancyGrid grid = mrslam::bench::trimUnknown(mrslam::loadMap(argv[1]));
    const int max_side = argc > 3 ? std::max(16, std::atoi(argv[3])) : 400;
    cv::Mat image(grid.height, grid.width, CV_8UC1);
    for (int row = 0; row < grid.height; ++row)
      for (int col = 0; col < grid.width; ++col) {
        const int v = grid.at(col, row);
        image.at<uint8_t>(grid.height - 1 - row, col) = v < 0 ? 205 : static_cast<uint8_t>(255 - v * 255 / 100);
      }
    const double scale = std::min(1.0, static_cast<double>(max_side) / std::max(grid.width, grid.height));
    if (scale < 1.0) cv::resize(image, image, cv::Size(), scale, scale, cv::INTER_AREA);
    if (!cv::imwrite(argv[2], image, {cv::IMWRITE_PNG_COMPRESSION, 9})) throw std::runtime_error(std::string(argv[2]) + ": cannot write");
  } catch (const std::exception& e) {
    std::cerr << "mrslam_map_picture: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
