#include "mrslam/slam/gyro_buffer.h"

#include <algorithm>
#include <cmath>

namespace mrslam::slam {

bool GyroBuffer::add(double stamp, double rate) {
  if (!std::isfinite(stamp) || !std::isfinite(rate)) return false;
  const auto at = std::upper_bound(samples_.begin(), samples_.end(), stamp,
                                   [](double t, const GyroSample& s) { return t < s.stamp; });
  samples_.insert(at, {stamp, rate});
  while (samples_.size() > capacity_) samples_.pop_front();
  return true;
}

std::optional<double> GyroBuffer::integrate(double t0, double t1) {
  double yaw = 0, covered = 0;
  for (size_t i = 0; i < samples_.size() && samples_[i].stamp < t1; ++i) {
    double until = samples_[i].stamp + max_gap_;
    if (i + 1 < samples_.size()) until = std::min(until, samples_[i + 1].stamp);
    const double start = std::max(t0, samples_[i].stamp), end = std::min(t1, until);
    if (end > start) yaw += samples_[i].rate * (end - start), covered += end - start;
  }
  while (samples_.size() > 1 && samples_[1].stamp <= t1) samples_.pop_front();
  // Rounding of the sums aside, every instant of the interval must lie under some sample.
  const double span = t1 - t0;
  if (!(span > 0) || covered < span - 1e-9 * std::max(1.0, span)) return std::nullopt;
  return yaw;
}

std::optional<double> GyroBuffer::newest() const {
  if (samples_.empty()) return std::nullopt;
  return samples_.back().stamp;
}

}  // namespace mrslam::slam
