#include "mrslam/fusion/chamfer_polish.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {
namespace {

// Bilinear read at continuous cell coordinates (cell centres at index + 0.5).
bool sample(const cv::Mat& image, double x, double y, float& out) {
  x -= 0.5, y -= 0.5;
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= image.cols || y0 + 1 >= image.rows) return false;
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const float* r0 = image.ptr<float>(y0) + x0;
  const float* r1 = image.ptr<float>(y0 + 1) + x0;
  out = (1 - fy) * ((1 - fx) * r0[0] + fx * r0[1]) + fy * ((1 - fx) * r1[0] + fx * r1[1]);
  return true;
}

}  // namespace

cv::Mat truncatedWallDistance(const cv::Mat& ternary, double reach) {
  // Only distances below `reach` are ever read, and walls are a few percent of the cells: each
  // wall stamps the exact Euclidean distance on its neighbourhood. Measured on a 1131 x 1068
  // ACES map: 3 ms, against 15 ms for cv::distanceTransform over the whole image.
  const int r = static_cast<int>(std::ceil(reach));
  const float cap = static_cast<float>(r);
  cv::Mat distance(ternary.size(), CV_32F, cv::Scalar(cap));
  std::vector<float> stamp;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) stamp.push_back(std::min(cap, static_cast<float>(std::hypot(dx, dy))));
  const int side = 2 * r + 1;
  for (int y = 0; y < ternary.rows; ++y) {
    const uint8_t* row = ternary.ptr<uint8_t>(y);
    for (int x = 0; x < ternary.cols; ++x) {
      if (row[x] != kOccupiedCell) continue;
      const int x0 = std::max(0, x - r), x1 = std::min(ternary.cols - 1, x + r);
      for (int yy = std::max(0, y - r); yy <= std::min(ternary.rows - 1, y + r); ++yy) {
        float* out = distance.ptr<float>(yy) + x0;
        const float* st = stamp.data() + static_cast<size_t>(yy - y + r) * side + (x0 - x + r);
        for (int k = 0; k <= x1 - x0; ++k) out[k] = std::min(out[k], st[k]);
      }
    }
  }
  return distance;
}

ChamferPolish::ChamferPolish(const cv::Mat& ternary_a, const cv::Mat& ternary_b, double truncation,
                             int max_points)
    : truncation_(truncation) {
  // Points below the truncation read their gradient half a cell away, bilinearly from cells
  // up to a cell beyond: exact up to truncation + 2 is all that is needed.
  distance_ = truncatedWallDistance(ternary_a, truncation + 2.0);

  std::vector<cv::Point> walls;
  cv::findNonZero(ternary_b == kOccupiedCell, walls);
  const size_t stride = std::max<size_t>(1, walls.size() / std::max(1, max_points));
  for (size_t i = 0; i < walls.size(); i += stride) {
    walls_b_.emplace_back(walls[i].x + 0.5f, walls[i].y + 0.5f);
    centre_b_ += cv::Point2d(walls_b_.back());
  }
  if (!walls_b_.empty()) centre_b_ /= static_cast<double>(walls_b_.size());
  for (auto& p : walls_b_) p -= cv::Point2f(centre_b_);
}

double ChamferPolish::meanDistance(const CellTransform& transform) const {
  const double c = std::cos(transform.theta), s = std::sin(transform.theta);
  const cv::Point2d t = transform.apply(centre_b_);  // where B's wall centroid lands
  double sum = 0;
  int n = 0;
  for (const auto& p : walls_b_) {
    float d;
    if (sample(distance_, c * p.x - s * p.y + t.x, s * p.x + c * p.y + t.y, d) && d < truncation_) sum += d, ++n;
  }
  return n > 0 ? sum / n : truncation_;
}

CellTransform ChamferPolish::polish(const CellTransform& start, int iterations) const {
  // Parameters: theta and the landing point t of B's wall centroid (well conditioned).
  double theta = start.theta;
  cv::Point2d t = start.apply(centre_b_);
  for (int it = 0; it < iterations; ++it) {
    const double c = std::cos(theta), s = std::sin(theta);
    cv::Matx33d h = cv::Matx33d::zeros();
    cv::Vec3d g(0, 0, 0);
    int used = 0;
    for (const auto& p : walls_b_) {
      const double qx = c * p.x - s * p.y + t.x, qy = s * p.x + c * p.y + t.y;
      float d, xp, xm, yp, ym;
      if (!sample(distance_, qx, qy, d) || d >= truncation_) continue;
      // Gradient by central differences of the interpolated distance (half-cell steps).
      if (!sample(distance_, qx + 0.5, qy, xp) || !sample(distance_, qx - 0.5, qy, xm) ||
          !sample(distance_, qx, qy + 0.5, yp) || !sample(distance_, qx, qy - 0.5, ym))
        continue;
      const double gx = xp - xm, gy = yp - ym;
      // d(q)/d(theta) = grad . (dR/dtheta p)
      const cv::Vec3d j(gx * (-s * p.x - c * p.y) + gy * (c * p.x - s * p.y), gx, gy);
      h += j * j.t();
      g += j * static_cast<double>(d);
      ++used;
    }
    if (used < 10) break;
    for (int k = 0; k < 3; ++k) h(k, k) += 1e-6 + 1e-3 * h(k, k);  // Levenberg damping
    const cv::Vec3d step = -(h.inv(cv::DECOMP_CHOLESKY) * g);
    theta += step[0];
    t += cv::Point2d(step[1], step[2]);
    if (std::abs(step[0]) < 1e-6 && std::hypot(step[1], step[2]) < 1e-3) break;
  }
  CellTransform out{theta, {0, 0}};
  out.t = t - out.apply(centre_b_);
  return out;
}

}  // namespace mrslam::fusion
