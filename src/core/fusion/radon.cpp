#include "mrslam/fusion/radon.h"

#include <algorithm>
#include <cmath>

#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {

std::vector<double> radonLineEnergy(const std::vector<cv::Point2f>& points, double start,
                                    double step, int count) {
  std::vector<double> energy(count, 0.0);
  if (points.empty()) return energy;
  float max_r = 0;
  for (const auto& p : points) max_r = std::max(max_r, std::hypot(p.x, p.y));
  const int offset = static_cast<int>(std::ceil(max_r)) + 1;
  std::vector<int> bins(2 * offset + 2);
  for (int k = 0; k < count; ++k) {
    const double theta = start + k * step;
    const float c = static_cast<float>(std::cos(theta)), s = static_cast<float>(std::sin(theta));
    std::fill(bins.begin(), bins.end(), 0);
    for (const auto& p : points) ++bins[static_cast<int>(std::lround(p.x * c + p.y * s)) + offset];
    double sum = 0;
    for (int b : bins) sum += static_cast<double>(b) * b;
    energy[k] = sum / points.size();
  }
  return energy;
}

double radonRotationTuning(const std::vector<cv::Point2f>& points_a,
                           const std::vector<cv::Point2f>& points_b_rotated, double window,
                           double step) {
  const int half = static_cast<int>(std::ceil(window / step));
  const int count = static_cast<int>(std::lround(M_PI / step));
  const std::vector<double> ea = radonLineEnergy(points_a, 0.0, step, count);
  const std::vector<double> eb = radonLineEnergy(points_b_rotated, 0.0, step, count);
  // Score a shift by the correlation restricted to the strongest directions of A, so the
  // peaks (walls) drive the result and the flat floor of the spectrum does not.
  const double threshold = *std::max_element(ea.begin(), ea.end()) * 0.25;
  int best_shift = 0;
  double best = -1;
  for (int shift = -half; shift <= half; ++shift) {
    double score = 0;
    for (int k = 0; k < count; ++k) {
      if (ea[k] < threshold) continue;
      score += ea[k] * eb[((k - shift) % count + count) % count];
    }
    if (score > best) best = score, best_shift = shift;
  }
  return best_shift * step;
}

std::vector<double> globalRotationCandidates(const std::vector<cv::Point2f>& points_a,
                                             const std::vector<cv::Point2f>& points_b,
                                             double step, int count) {
  const int n = static_cast<int>(std::lround(M_PI / step));
  std::vector<double> ea = radonLineEnergy(points_a, 0.0, step, n);
  std::vector<double> eb = radonLineEnergy(points_b, 0.0, step, n);
  // Remove the mean so that correlation measures the alignment of peaks, not their height.
  auto center = [](std::vector<double>& e) {
    double mean = 0;
    for (double v : e) mean += v;
    mean /= e.size();
    for (double& v : e) v -= mean;
  };
  center(ea);
  center(eb);
  std::vector<double> corr(n, 0.0);
  for (int shift = 0; shift < n; ++shift)
    for (int k = 0; k < n; ++k) corr[shift] += ea[k] * eb[((k - shift) % n + n) % n];

  std::vector<std::pair<double, int>> peaks;
  for (int i = 0; i < n; ++i) {
    const double v = corr[i];
    if (v >= corr[(i + 1) % n] && v > corr[(i + n - 1) % n]) peaks.emplace_back(v, i);
  }
  std::sort(peaks.rbegin(), peaks.rend());
  std::vector<double> out;
  for (size_t i = 0; i < peaks.size() && static_cast<int>(out.size()) < count; ++i)
    out.push_back(peaks[i].second * step);
  return out;
}

std::vector<cv::Point2f> occupiedPoints(const cv::Mat& ternary) {
  std::vector<cv::Point2f> points;
  for (int r = 0; r < ternary.rows; ++r) {
    const uint8_t* row = ternary.ptr<uint8_t>(r);
    for (int c = 0; c < ternary.cols; ++c)
      if (row[c] == kOccupiedCell) points.emplace_back(c + 0.5f, r + 0.5f);
  }
  return points;
}

}  // namespace mrslam::fusion
