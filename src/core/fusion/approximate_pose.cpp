#include "mrslam/fusion/approximate_pose.h"

#include <opencv2/imgproc.hpp>

namespace mrslam::fusion {
namespace {

double lineDirection(const Segment& segment) {
  cv::Vec4f line;
  cv::fitLine(segment, line, cv::DIST_L2, 0, 0.01, 0.01);
  return std::atan2(line[1], line[0]);
}

cv::Point2d centroid(const Segment& segment) {
  cv::Point2d sum(0, 0);
  for (const auto& p : segment) sum += cv::Point2d(p);
  return sum / static_cast<double>(segment.size());
}

}  // namespace

std::array<CellTransform, 2> approximatePose(const Segment& segment_a, const Segment& segment_b) {
  const double alpha = std::remainder(lineDirection(segment_a) - lineDirection(segment_b), 2 * M_PI);
  const cv::Point2d ca = centroid(segment_a), cb = centroid(segment_b);
  std::array<CellTransform, 2> out;
  for (int k = 0; k < 2; ++k) {
    out[k].theta = std::remainder(alpha + k * M_PI, 2 * M_PI);
    out[k].t = ca - CellTransform{out[k].theta, {0, 0}}.apply(cb);
  }
  return out;
}

}  // namespace mrslam::fusion
