// Stage 1 of the paper's map fusion: the occupancy grid as a ternary image
// (unknown / free / occupied) and the Canny edges of its obstacles.
//
// Images produced by the fusion code keep the grid's row order (row 0 = lowest y), so a
// rotation in image coordinates is a proper rotation of the map frame.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

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

// How many cells of a ternary image are in `state` (no whole-image mask).
int countCells(const cv::Mat& ternary, CellState state);

// Keeps every stride-th cell that a row of 0/1 `marks` flags, in raster order across rows: the
// 1st, (stride + 1)th, ... flagged cell of the image, `countdown` (1 before the first row)
// carrying the count from row to row. Appends each kept cell's centre (x + 0.5, y + 0.5).
void keepEveryStrideth(const uint8_t* marks, int cols, int y, size_t stride, size_t& countdown,
                       std::vector<cv::Point2f>& out);

// Centres of the 1st, (stride + 1)th, ... cell in `state`, in raster order.
std::vector<cv::Point2f> everyStridethCell(const cv::Mat& ternary, CellState state, size_t stride);

// Row by row, the cells with a wall in their 3 x 3 neighbourhood (themselves included), which
// is the walls dilated by one cell (cv::dilate, 3 x 3 square), without the whole-image masks
// that costs: on a 4000 x 4000 map each mask is 16 MB of fresh pages. Calls
// visit(y, cells, near) for every row in order, `cells` the row's states and near[x] 1 where a
// wall is that close, else 0.
template <typename Visit>
void forEachRowWithWallsNear(const cv::Mat& ternary, Visit&& visit) {
  const int rows = ternary.rows, cols = ternary.cols;
  // walls_across[k][x]: a wall in row y - 1 + k within one column of x (a ring over the rows);
  // walls: one row's walls with an empty cell either side. Plain loops the compiler vectorises.
  std::vector<uint8_t> walls_across[3], walls(static_cast<size_t>(cols) + 2, 0), near(static_cast<size_t>(cols));
  auto across = [&](int y, std::vector<uint8_t>& out) {
    out.assign(static_cast<size_t>(cols), 0);
    if (y < 0 || y >= rows) return;
    const uint8_t* cells = ternary.ptr<uint8_t>(y);
    for (int x = 0; x < cols; ++x) walls[x + 1] = cells[x] == kOccupiedCell;
    for (int x = 0; x < cols; ++x) out[x] = walls[x] | walls[x + 1] | walls[x + 2];
  };
  across(-1, walls_across[0]);
  across(0, walls_across[1]);
  for (int y = 0; y < rows; ++y) {
    across(y + 1, walls_across[(y + 2) % 3]);
    const uint8_t *above = walls_across[y % 3].data(), *same = walls_across[(y + 1) % 3].data(),
                  *below = walls_across[(y + 2) % 3].data();
    for (int x = 0; x < cols; ++x) near[x] = above[x] | same[x] | below[x];
    visit(y, ternary.ptr<uint8_t>(y), near.data());
  }
}

}  // namespace mrslam::fusion
