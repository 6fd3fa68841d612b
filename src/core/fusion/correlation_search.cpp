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
  // Packed (CCS) spectrum of a real image: half the work of a complex one; the rows below the
  // image are zero padding, which nonzeroRows lets the row pass skip.
  cv::dft(f, out, 0, image.rows);
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
                                     double disagreement_weight)
    : ternary_b_(ternary_b) {
  const int diagonal = static_cast<int>(std::ceil(std::hypot(ternary_b.rows, ternary_b.cols))) + 2;
  padded_ = {cv::getOptimalDFTSize(ternary_a.cols + diagonal), cv::getOptimalDFTSize(ternary_a.rows + diagonal)};
  // A's cell classes as in SimilarityIndex: wall, near a wall (within one cell), free.
  const cv::Mat walls = mask(ternary_a, kOccupiedCell);
  cv::Mat wall_or_near;
  cv::dilate(walls, wall_or_near, cv::Mat::ones(3, 3, CV_8U));
  const cv::Mat near = wall_or_near - walls;
  const cv::Mat free = mask(ternary_a, kFreeCell).mul(1.0f - wall_or_near);
  const double w = disagreement_weight;
  spectrum_for_b_walls_ = spectrum(wall_or_near - w * free, padded_);
  spectrum_for_b_free_ = spectrum(free + near - w * walls, padded_);
}

namespace {

// The `count` best peaks of `score` with non-maximum suppression (cyclic, like the transform).
std::vector<cv::Point> peaks(cv::Mat score, int count, int separation) {
  std::vector<cv::Point> out;
  for (int k = 0; k < count; ++k) {
    double best;
    cv::Point at;
    cv::minMaxLoc(score, nullptr, &best, nullptr, &at);
    if (!(best > -1e29)) break;
    out.push_back(at);
    for (int dy = -separation; dy <= separation; ++dy)
      for (int dx = -separation; dx <= separation; ++dx)
        score.at<float>((at.y + dy + score.rows) % score.rows, (at.x + dx + score.cols) % score.cols) = -1e30f;
  }
  return out;
}

}  // namespace

std::vector<CellTransform> CorrelationSearch::candidates(double theta, int count, int separation) const {
  cv::Point2d offset;
  const cv::Mat rotated = rotateTernary(ternary_b_, theta, offset);
  // B's free cells next to its own walls are not counted (as in SimilarityIndex).
  const cv::Mat walls = mask(rotated, kOccupiedCell);
  cv::Mat near_walls;
  cv::dilate(walls, near_walls, cv::Mat::ones(3, 3, CV_8U));
  const cv::Mat free = mask(rotated, kFreeCell).mul(1.0f - near_walls);
  const cv::Mat g_walls = spectrum(walls, padded_), g_free = spectrum(free, padded_);
  std::vector<CellTransform> out;
  for (const bool reflected : {false, true}) {
    // score(s) = sum_v f(v) g(v - s) = correlation; for the reflected canvas g(C - v + s),
    // which is the convolution (f * g)(C + s), C = canvas size - 1.
    cv::Mat product, second, score;
    cv::mulSpectrums(spectrum_for_b_walls_, g_walls, product, 0, !reflected);
    cv::mulSpectrums(spectrum_for_b_free_, g_free, second, 0, !reflected);
    product += second;
    cv::idft(product, score, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
    for (const cv::Point& at : peaks(score, count, separation)) {
      if (!reflected) {
        // Stored at s mod padded size; s = A pixel - B' pixel may be negative.
        const int sx = at.x >= padded_.width - rotated.cols ? at.x - padded_.width : at.x;
        const int sy = at.y >= padded_.height - rotated.rows ? at.y - padded_.height : at.y;
        out.push_back({theta, cv::Point2d(sx, sy) + offset});
      } else {
        // Reflected canvas coordinates: (W', H') - (R u + offset) = R(theta + pi) u + offset''.
        const cv::Point2d s(at.x - (rotated.cols - 1), at.y - (rotated.rows - 1));
        out.push_back({theta + M_PI, s + cv::Point2d(rotated.cols, rotated.rows) - offset});
      }
    }
  }
  return out;
}

}  // namespace mrslam::fusion
