#include <chrono>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>

#include "mrslam/bench/peers.h"
#include "mrslam/fusion/map_fusion.h"

namespace mrslam::bench {
namespace {

// m-explore feeds the grid data itself as an 8-bit image: 0..100 occupancy, unknown = 255.
cv::Mat gridImage(const OccupancyGrid& g) {
  cv::Mat image(g.height, g.width, CV_8U);
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c) image.at<uint8_t>(r, c) = static_cast<uint8_t>(g.at(c, r));
  return image;
}

}  // namespace

PeerResult alignWithAkaze(const OccupancyGrid& a, const OccupancyGrid& b) {
  const auto start = std::chrono::steady_clock::now();
  PeerResult out;
  const cv::Ptr<cv::AKAZE> akaze = cv::AKAZE::create();
  std::vector<cv::KeyPoint> ka, kb;
  cv::Mat da, db;
  akaze->detectAndCompute(gridImage(a), cv::noArray(), ka, da);
  akaze->detectAndCompute(gridImage(b), cv::noArray(), kb, db);
  std::vector<cv::Point2f> from, to;
  if (!da.empty() && !db.empty()) {
    cv::BFMatcher matcher(cv::NORM_HAMMING);
    std::vector<std::vector<cv::DMatch>> knn;
    matcher.knnMatch(db, da, knn, 2);
    for (const auto& m : knn)  // OpenCV's BestOf2NearestMatcher ratio with match_conf 0.3
      if (m.size() == 2 && m[0].distance < 0.7f * m[1].distance) {
        from.push_back(kb[m[0].queryIdx].pt);
        to.push_back(ka[m[0].trainIdx].pt);
      }
  }
  if (from.size() >= 3) {
    std::vector<uchar> inliers;
    const cv::Mat m = cv::estimateAffinePartial2D(from, to, inliers, cv::RANSAC, 3.0);
    const double n_inliers = cv::countNonZero(inliers);
    const double confidence = n_inliers / (8.0 + 0.3 * from.size());
    if (!m.empty() && confidence >= 1.0) {
      // Pixel index p maps to cell coordinate p + 0.5 (rows in grid order, as fed).
      const double theta = std::atan2(m.at<double>(1, 0), m.at<double>(0, 0));
      const fusion::CellTransform rotation{theta, {0, 0}};
      const cv::Point2d t = cv::Point2d(m.at<double>(0, 2), m.at<double>(1, 2)) + cv::Point2d(0.5, 0.5) -
                            rotation.apply({0.5, 0.5});
      out.accepted = true;
      out.pose = fusion::poseFromCells(a, b, {theta, t});
    }
  }
  out.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace mrslam::bench
