#include "mrslam/fusion/segment.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace mrslam::fusion {
namespace {

constexpr int kDx[8] = {1, 1, 0, -1, -1, -1, 0, 1};
constexpr int kDy[8] = {0, 1, 1, 1, 0, -1, -1, -1};

std::vector<double> histogram(const std::vector<double>& values, int bins, double lo, double hi) {
  std::vector<double> h(bins, 0.0);
  const double width = (hi - lo) / bins;
  if (!(width > 0)) {
    h[0] = static_cast<double>(values.size());
    return h;
  }
  for (double v : values) {
    const int b = std::clamp(static_cast<int>((v - lo) / width), 0, bins - 1);
    h[b] += 1.0;
  }
  return h;
}

}  // namespace

std::optional<Segment> randomSegment(const cv::Mat& skeleton,
                                     const std::vector<cv::Point>& curve_points, int n,
                                     std::mt19937& rng) {
  if (curve_points.empty() || n < 2) return std::nullopt;
  std::uniform_int_distribution<size_t> pick(0, curve_points.size() - 1);
  cv::Point p = curve_points[pick(rng)];
  Segment segment{cv::Point2f(p)};
  cv::Point previous = p;
  int heading = -1;
  while (static_cast<int>(segment.size()) < n) {
    // Prefer the neighbour whose direction is closest to the current heading, never going back.
    int best = -1, best_turn = 9;
    for (int k = 0; k < 8; ++k) {
      const cv::Point q(p.x + kDx[k], p.y + kDy[k]);
      if (q.x < 0 || q.y < 0 || q.x >= skeleton.cols || q.y >= skeleton.rows) continue;
      if (!skeleton.at<uint8_t>(q) || q == previous) continue;
      bool seen = false;
      for (size_t i = segment.size() >= 4 ? segment.size() - 4 : 0; i < segment.size(); ++i)
        seen |= (cv::Point(segment[i]) == q);
      if (seen) continue;
      const int turn = heading < 0 ? 0 : std::min((k - heading + 8) % 8, (heading - k + 8) % 8);
      if (turn < best_turn) best_turn = turn, best = k;
    }
    if (best < 0) return std::nullopt;
    previous = p;
    p = cv::Point(p.x + kDx[best], p.y + kDy[best]);
    heading = best;
    segment.emplace_back(p);
  }
  return segment;
}

SegmentSignature computeSignature(const Segment& segment, const SegmentParams& params) {
  SegmentSignature s;
  const cv::Point2f p0 = segment.front();
  double previous_angle = 0.0, swept = 0.0;
  for (size_t i = 1; i < segment.size(); ++i) {
    const cv::Point2f v = segment[i] - p0;
    const double d = std::hypot(v.x, v.y);
    const double angle = std::atan2(v.y, v.x);
    // delta_1 is measured from the direction of P(1) itself, so it is 0.
    const double delta = i == 1 ? 0.0 : std::remainder(angle - previous_angle, 2.0 * M_PI);
    previous_angle = angle;
    s.D.push_back(d);
    s.delta.push_back(delta);
    swept += delta;
    s.omega.push_back(d * swept);  // omega_i = d_{i+1} * sum_{j<=i} delta_j (0-based here)
  }
  const double max_d = *std::max_element(s.D.begin(), s.D.end());
  s.hist_d = histogram(s.D, params.distance_bins, 0.0, max_d);
  s.hist_a = histogram(s.omega, params.arc_bins, -params.omega_c, params.omega_c);
  return s;
}

bool verifySegment(const SegmentSignature& s, const SegmentParams& params, std::string* why) {
  auto reject = [&](const char* reason) {
    if (why) *why = reason;
    return false;
  };
  if (std::any_of(s.hist_d.begin(), s.hist_d.end(), [](double h) { return h == 0.0; }))
    return reject("condition 1: empty distance-histogram bin");
  const auto [mn, mx] = std::minmax_element(s.hist_d.begin(), s.hist_d.end());
  if (*mx - *mn < params.h_d) return reject("condition 2: distance histogram is flat");
  double max_omega = 0.0;
  for (double w : s.omega) max_omega = std::max(max_omega, std::abs(w));
  if (!(max_omega < params.omega_c)) return reject("condition 3: discontinuity in the arc vector");
  return true;
}

double normalizedCorrelation(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = std::min(a.size(), b.size());
  if (n == 0) return 0.0;
  const double ma = std::accumulate(a.begin(), a.begin() + n, 0.0) / n;
  const double mb = std::accumulate(b.begin(), b.begin() + n, 0.0) / n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < n; ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  if (saa <= 1e-12 || sbb <= 1e-12) return 0.0;
  return sab / std::sqrt(saa * sbb);
}

double segmentCorrelation(const SegmentSignature& a, const SegmentSignature& b) {
  return std::min({normalizedCorrelation(a.hist_d, b.hist_d),
                   normalizedCorrelation(a.hist_a, b.hist_a), normalizedCorrelation(a.D, b.D),
                   normalizedCorrelation(a.omega, b.omega)});
}

}  // namespace mrslam::fusion
