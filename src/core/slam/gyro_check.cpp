#include "mrslam/slam/gyro_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace mrslam::slam {

bool GyroCheck::observe(double odometry_turn, double gyro_turn) {
  if (refused() || params_.turns <= 0 || !std::isfinite(odometry_turn) || !std::isfinite(gyro_turn)) return false;
  if (std::abs(odometry_turn) < params_.min_turn) return false;
  ratios_.push_back(gyro_turn / odometry_turn);
  // A window, so that a gyro that breaks during a run is caught as well.
  while (ratios_.size() > 2 * static_cast<size_t>(params_.turns)) ratios_.pop_front();
  if (ratios_.size() < static_cast<size_t>(params_.turns)) return false;
  std::vector<double> sorted(ratios_.begin(), ratios_.end());
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median = sorted[sorted.size() / 2];
  if (median >= 1.0 / params_.max_ratio && median <= params_.max_ratio) return false;
  char text[200];
  std::snprintf(text, sizeof text,
                "the gyro turned %.2f times as far as the odometry (median of %zu turns): set aside for the run; "
                "check its frame in tf and that it reports rad/s",
                median, ratios_.size());
  problem_ = text;
  return true;
}

}  // namespace mrslam::slam
