#include "mrslam/fusion/radon.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {

std::vector<double> radonLineEnergy(const std::vector<cv::Point2f>& points, double start,
                                    double step, int count) {
  std::vector<double> energy(count, 0.0);
  if (points.empty()) return energy;
  float max_r = 0;
  for (const auto& p : points) max_r = std::max(max_r, std::hypot(p.x, p.y));
  // rho + offset is never negative, so truncating rho + offset + 0.5 rounds to the nearest bin.
  const float offset = std::ceil(max_r) + 1.5f;
  // Neighbouring points (a wall, in raster order) fall in the same bin: four interleaved
  // histograms break the chain of increments of one counter (about 2x faster, measured).
  const size_t n_bins = 2 * static_cast<size_t>(offset) + 3;
  std::vector<int> bins(4 * n_bins);
  int* const h0 = bins.data();
  int* const h1 = h0 + n_bins;
  int* const h2 = h1 + n_bins;
  int* const h3 = h2 + n_bins;
  const size_t n = points.size(), n4 = n - n % 4;
  for (int k = 0; k < count; ++k) {
    const double theta = start + k * step;
    const float c = static_cast<float>(std::cos(theta)), s = static_cast<float>(std::sin(theta));
    std::fill(bins.begin(), bins.end(), 0);
    auto bin = [&](size_t i) { return static_cast<int>(points[i].x * c + points[i].y * s + offset); };
    for (size_t i = 0; i < n4; i += 4) {
      ++h0[bin(i)];
      ++h1[bin(i + 1)];
      ++h2[bin(i + 2)];
      ++h3[bin(i + 3)];
    }
    for (size_t i = n4; i < n; ++i) ++h0[bin(i)];
    double sum = 0;
    for (size_t b = 0; b < n_bins; ++b) {
      const double v = h0[b] + h1[b] + h2[b] + h3[b];
      sum += v * v;
    }
    energy[k] = sum / points.size();
  }
  return energy;
}

RadonTuner::RadonTuner(const std::vector<cv::Point2f>& points_a, double window, double step, int peaks)
    : step_(step), half_(static_cast<int>(std::ceil(window / step))) {
  // The strongest line directions of A (local maxima of a 1-degree spectrum) decide; the fine
  // spectra are computed only around them.
  constexpr int kCoarse = 180;
  const double coarse_step = M_PI / kCoarse;
  const std::vector<double> coarse = radonLineEnergy(points_a, 0.0, coarse_step, kCoarse);
  std::vector<std::pair<double, int>> maxima;
  for (int k = 0; k < kCoarse; ++k)
    if (coarse[k] >= coarse[(k + 1) % kCoarse] && coarse[k] > coarse[(k + kCoarse - 1) % kCoarse])
      maxima.emplace_back(coarse[k], k);
  std::sort(maxima.rbegin(), maxima.rend());
  for (size_t i = 0; i < maxima.size() && static_cast<int>(i) < peaks; ++i) {
    if (maxima[i].first < 0.25 * maxima.front().first) break;
    const double centre = maxima[i].second * coarse_step;
    peaks_.push_back({centre, radonLineEnergy(points_a, centre - half_ * step_, step_, 2 * half_ + 1)});
  }
}

double RadonTuner::tune(const std::vector<cv::Point2f>& points_b_rotated) const {
  std::vector<double> score(2 * half_ + 1, 0.0);
  const double core = peaks_.empty() ? 0.0 : 0.25 * *std::max_element(peaks_[0].energy_a.begin(), peaks_[0].energy_a.end());
  for (const Peak& peak : peaks_) {
    // B around the peak (+- 2 window), so every shift of A's window is covered. Only the core
    // of A's peaks takes part: the flanks are where rasterisation differs most.
    const auto eb = radonLineEnergy(points_b_rotated, peak.centre - 2 * half_ * step_, step_, 4 * half_ + 1);
    for (int shift = -half_; shift <= half_; ++shift)
      for (int j = 0; j <= 2 * half_; ++j)
        if (peak.energy_a[j] >= core) score[shift + half_] += peak.energy_a[j] * eb[j + half_ - shift];
  }
  const int best = static_cast<int>(std::max_element(score.begin(), score.end()) - score.begin());
  return (best - half_) * step_;
}

double radonRotationTuning(const std::vector<cv::Point2f>& points_a,
                           const std::vector<cv::Point2f>& points_b_rotated, double window,
                           double step) {
  return RadonTuner(points_a, window, step).tune(points_b_rotated);
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
    // Walls are sparse: memchr finds the next one.
    const uint8_t* const row = ternary.ptr<uint8_t>(r);
    const uint8_t* const end = row + ternary.cols;
    for (const uint8_t* wall = row;; ++wall) {
      wall = static_cast<const uint8_t*>(std::memchr(wall, kOccupiedCell, end - wall));
      if (!wall) break;
      points.emplace_back(static_cast<float>(wall - row) + 0.5f, r + 0.5f);
    }
  }
  return points;
}

}  // namespace mrslam::fusion
