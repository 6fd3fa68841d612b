// Stage 1 of the paper's map fusion: the occupancy grid as a ternary image
// (unknown / free / occupied) and the Canny edges of its obstacles.
//
// Images produced by the fusion code keep the grid's row order (row 0 = lowest y), so a
// rotation in image coordinates is a proper rotation of the map frame.
#pragma once

#include <opencv2/core.hpp>

#include "mrslam/grid.h"

namespace mrslam::fusion {

enum CellState : uint8_t { kUnknownCell = 0, kFreeCell = 1, kOccupiedCell = 2 };

// Cells >= occupied_threshold are occupied, 0 <= v <= free_threshold free, the rest unknown
// (map_saver's rule, so a saved and reloaded map gives the same ternary image).
cv::Mat toTernary(const OccupancyGrid& grid, int occupied_threshold = 65, int free_threshold = 25);

struct CannyParams {
  double blur_sigma = 0.8;   // Gaussian smoothing before Canny removes isolated noise cells
  double low_threshold = 50;
  double high_threshold = 150;
};

// Canny edges (CV_8U, 0/255) of the obstacle boundaries. Edges between free and unknown
// space say nothing about the building and are dropped: only edge pixels within one cell
// of an occupied cell are kept.
cv::Mat cannyEdges(const cv::Mat& ternary, const CannyParams& params);

// Image pyramid step for ternary images: a 2x2 block is occupied if any cell is occupied,
// else free if any is free, else unknown. Occupied-wins keeps one-cell walls visible.
cv::Mat downsampleTernary(const cv::Mat& ternary);

}  // namespace mrslam::fusion
