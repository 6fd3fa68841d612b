#include "mrslam/fusion/edge_smoothing.h"

#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc.hpp>

namespace mrslam::fusion {

cv::Mat smoothEdges(const cv::Mat& edges, int distance_threshold_cells) {
  cv::Mat joined = edges.clone();
  if (distance_threshold_cells > 0) {
    const int k = 2 * distance_threshold_cells + 1;
    cv::morphologyEx(edges, joined, cv::MORPH_CLOSE,
                     cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)));
  }
  cv::Mat middle;
  cv::ximgproc::thinning(joined, middle, cv::ximgproc::THINNING_ZHANGSUEN);
  return middle;
}

}  // namespace mrslam::fusion
