#include "mrslam/fusion/ternary_image.h"

#include <opencv2/imgproc.hpp>

namespace mrslam::fusion {

cv::Mat toTernary(const OccupancyGrid& grid, int occupied_threshold, int free_threshold) {
  cv::Mat out(grid.height, grid.width, CV_8U);
  for (int r = 0; r < grid.height; ++r) {
    const int8_t* src = grid.data.data() + static_cast<size_t>(r) * grid.width;
    uint8_t* dst = out.ptr<uint8_t>(r);
    for (int c = 0; c < grid.width; ++c) {
      const int v = src[c];
      dst[c] = v < 0 ? kUnknownCell
                     : (v >= occupied_threshold ? kOccupiedCell
                                                : (v <= free_threshold ? kFreeCell : kUnknownCell));
    }
  }
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
  cv::Mat out((ternary.rows + 1) / 2, (ternary.cols + 1) / 2, CV_8U);
  for (int r = 0; r < out.rows; ++r) {
    for (int c = 0; c < out.cols; ++c) {
      uint8_t best = kUnknownCell;
      for (int dr = 0; dr < 2; ++dr) {
        const int rr = 2 * r + dr;
        if (rr >= ternary.rows) break;
        const uint8_t* src = ternary.ptr<uint8_t>(rr);
        for (int dc = 0; dc < 2; ++dc) {
          const int cc = 2 * c + dc;
          if (cc < ternary.cols && src[cc] > best) best = src[cc];  // occupied > free > unknown
        }
      }
      out.at<uint8_t>(r, c) = best;
    }
  }
  return out;
}

}  // namespace mrslam::fusion
