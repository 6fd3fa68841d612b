#include "mrslam/fusion/ternary_image.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>

namespace mrslam::fusion {

cv::Mat toTernary(const OccupancyGrid& grid, int occupied_threshold, int free_threshold) {
  // One table lookup per cell (cv::LUT is vectorised) on the int8 values read as bytes.
  cv::Mat table(1, 256, CV_8U);
  for (int i = 0; i < 256; ++i) {
    const int v = static_cast<int8_t>(static_cast<uint8_t>(i));
    table.at<uint8_t>(i) = v < 0 ? kUnknownCell
                                 : (v >= occupied_threshold ? kOccupiedCell
                                                            : (v <= free_threshold ? kFreeCell : kUnknownCell));
  }
  const cv::Mat values(grid.height, grid.width, CV_8U, const_cast<int8_t*>(grid.data.data()));
  cv::Mat out;
  cv::LUT(values, table, out);
  return out;
}

cv::Mat cannyEdges(const cv::Mat& ternary, const CannyParams& params) {
  // Render as a map image (occupied dark, unknown grey, free bright) like the paper's maps.
  cv::Mat image(ternary.size(), CV_8U);
  const uint8_t lut_values[3] = {128, 255, 0};
  for (int r = 0; r < ternary.rows; ++r) {
    const uint8_t* src = ternary.ptr<uint8_t>(r);
    uint8_t* dst = image.ptr<uint8_t>(r);
    for (int c = 0; c < ternary.cols; ++c) dst[c] = lut_values[src[c]];
  }
  if (params.blur_sigma > 0) cv::GaussianBlur(image, image, cv::Size(0, 0), params.blur_sigma);
  cv::Mat edges;
  cv::Canny(image, edges, params.low_threshold, params.high_threshold);

  cv::Mat near_occupied = (ternary == kOccupiedCell);
  cv::dilate(near_occupied, near_occupied, cv::Mat::ones(3, 3, CV_8U));
  cv::bitwise_and(edges, near_occupied, edges);
  return edges;
}

cv::Mat downsampleTernary(const cv::Mat& ternary) {
  // The maximum of each 2 x 2 block (occupied > free > unknown); a last odd row or column makes
  // half blocks. One pass with a row of scratch: the max of each row pair, then of each column
  // pair (whole-image temporaries cost a large map fresh pages).
  const int rows = (ternary.rows + 1) / 2, cols = (ternary.cols + 1) / 2;
  cv::Mat out(rows, cols, CV_8U);
  std::vector<uint8_t> row_pair_max(2 * static_cast<size_t>(cols), kUnknownCell);  // even width
  for (int r = 0; r < rows; ++r) {
    const uint8_t* top = ternary.ptr<uint8_t>(2 * r);
    const uint8_t* bottom = 2 * r + 1 < ternary.rows ? ternary.ptr<uint8_t>(2 * r + 1) : top;
    for (int c = 0; c < ternary.cols; ++c) row_pair_max[c] = std::max(top[c], bottom[c]);
    uint8_t* block_max = out.ptr<uint8_t>(r);
    for (int c = 0; c < cols; ++c) block_max[c] = std::max(row_pair_max[2 * c], row_pair_max[2 * c + 1]);
  }
  return out;
}

int countCells(const cv::Mat& ternary, CellState state) {
  int count = 0;
  for (int y = 0; y < ternary.rows; ++y) {
    const uint8_t* row = ternary.ptr<uint8_t>(y);
    for (int x = 0; x < ternary.cols; ++x) count += row[x] == state;
  }
  return count;
}

void keepEveryStrideth(const uint8_t* marks, int cols, int y, size_t stride, size_t& countdown,
                       std::vector<cv::Point2f>& out) {
  // Whole chunks holding fewer flags than the countdown are only counted (a loop the compiler
  // vectorises): with a stride of hundreds most of a row is skipped that way.
  constexpr int kChunk = 64;
  for (int x0 = 0; x0 < cols; x0 += kChunk) {
    const int x1 = std::min(cols, x0 + kChunk);
    unsigned flagged = 0;
    for (int x = x0; x < x1; ++x) flagged += marks[x];
    if (flagged < countdown) {
      countdown -= flagged;
      continue;
    }
    for (int x = x0; x < x1; ++x)
      if (marks[x] && --countdown == 0) out.emplace_back(x + 0.5f, y + 0.5f), countdown = stride;
  }
}

std::vector<cv::Point2f> everyStridethCell(const cv::Mat& ternary, CellState state, size_t stride) {
  std::vector<cv::Point2f> out;
  std::vector<uint8_t> marks(static_cast<size_t>(ternary.cols));
  size_t countdown = 1;
  for (int y = 0; y < ternary.rows; ++y) {
    const uint8_t* row = ternary.ptr<uint8_t>(y);
    for (int x = 0; x < ternary.cols; ++x) marks[x] = row[x] == state;
    keepEveryStrideth(marks.data(), ternary.cols, y, stride, countdown, out);
  }
  return out;
}

}  // namespace mrslam::fusion
