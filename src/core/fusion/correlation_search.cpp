#include "mrslam/fusion/correlation_search.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {
namespace {

cv::Mat spectrum(const cv::Mat& image, cv::Size padded) {
  cv::Mat f = cv::Mat::zeros(padded, CV_32F);
  image.convertTo(f(cv::Rect(0, 0, image.cols, image.rows)), CV_32F);
  cv::Mat out;
  cv::dft(f, out, cv::DFT_COMPLEX_OUTPUT);
  return out;
}

cv::Mat mask(const cv::Mat& ternary, uint8_t state) {
  cv::Mat m = ternary == state;
  m.convertTo(m, CV_32F, 1.0 / 255.0);
  return m;
}

}  // namespace

cv::Mat rotateTernary(const cv::Mat& ternary, double theta, cv::Point2d& offset) {
  const double c = std::cos(theta), s = std::sin(theta);
  double min_x = 1e300, min_y = 1e300, max_x = -1e300, max_y = -1e300;
  for (const cv::Point2d corner : {cv::Point2d(0, 0), cv::Point2d(ternary.cols, 0),
                                   cv::Point2d(0, ternary.rows), cv::Point2d(ternary.cols, ternary.rows)}) {
    const double x = c * corner.x - s * corner.y, y = s * corner.x + c * corner.y;
    min_x = std::min(min_x, x), max_x = std::max(max_x, x);
    min_y = std::min(min_y, y), max_y = std::max(max_y, y);
  }
  offset = {-min_x, -min_y};
  const cv::Size size(static_cast<int>(std::ceil(max_x - min_x)), static_cast<int>(std::ceil(max_y - min_y)));
  // OpenCV works on pixel indices (centre = index); our cell coordinates put centres at +0.5.
  const cv::Matx23d m(c, -s, offset.x + (c * 0.5 - s * 0.5) - 0.5,  //
                      s, c, offset.y + (s * 0.5 + c * 0.5) - 0.5);
  cv::Mat out;
  cv::warpAffine(ternary, out, m, size, cv::INTER_NEAREST, cv::BORDER_CONSTANT, kUnknownCell);
  return out;
}

CorrelationSearch::CorrelationSearch(const cv::Mat& ternary_a, const cv::Mat& ternary_b,
                                     double conflict_penalty)
    : ternary_b_(ternary_b), penalty_(conflict_penalty) {
  const int diagonal = static_cast<int>(std::ceil(std::hypot(ternary_b.rows, ternary_b.cols))) + 2;
  padded_ = {cv::getOptimalDFTSize(ternary_a.cols + diagonal), cv::getOptimalDFTSize(ternary_a.rows + diagonal)};
  const cv::Mat walls = mask(ternary_a, kOccupiedCell);
  cv::Mat blurred;
  cv::GaussianBlur(walls, blurred, cv::Size(0, 0), 1.0);
  double peak = 0;
  cv::minMaxLoc(blurred, nullptr, &peak);
  if (peak > 0) blurred = cv::min(blurred * (2.0 / peak), 1.0);  // a wall cell and its neighbours score ~1
  spectrum_walls_a_ = spectrum(blurred - penalty_ * mask(ternary_a, kFreeCell), padded_);
  spectrum_walls_only_a_ = spectrum(walls, padded_);
}

std::vector<CellTransform> CorrelationSearch::candidates(double theta, int count, int separation) const {
  cv::Point2d offset;
  const cv::Mat rotated = rotateTernary(ternary_b_, theta, offset);
  const cv::Mat g_walls = spectrum(mask(rotated, kOccupiedCell), padded_);
  const cv::Mat g_free = spectrum(mask(rotated, kFreeCell), padded_);
  cv::Mat product, conflicts;
  cv::mulSpectrums(spectrum_walls_a_, g_walls, product, 0, true);
  cv::mulSpectrums(spectrum_walls_only_a_, g_free, conflicts, 0, true);
  product -= penalty_ * conflicts;
  cv::Mat score;
  cv::idft(product, score, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);

  // score(s) = sum_v f(v) g(v - s), stored at s mod padded size; s = A pixel - B' pixel.
  std::vector<CellTransform> out;
  cv::Mat suppressed = score.clone();
  for (int k = 0; k < count; ++k) {
    double best;
    cv::Point at;
    cv::minMaxLoc(suppressed, nullptr, &best, nullptr, &at);
    if (!(best > 0)) break;
    const int sx = at.x >= padded_.width - rotated.cols ? at.x - padded_.width : at.x;
    const int sy = at.y >= padded_.height - rotated.rows ? at.y - padded_.height : at.y;
    out.push_back({theta, cv::Point2d(sx, sy) + offset});
    // Suppress the neighbourhood (with wrap-around, as the correlation is cyclic).
    for (int dy = -separation; dy <= separation; ++dy)
      for (int dx = -separation; dx <= separation; ++dx)
        suppressed.at<float>((at.y + dy + padded_.height) % padded_.height,
                             (at.x + dx + padded_.width) % padded_.width) = -1e30f;
  }
  return out;
}

}  // namespace mrslam::fusion
