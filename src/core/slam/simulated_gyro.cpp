#include "mrslam/slam/simulated_gyro.h"

#include <cmath>

namespace mrslam::slam {

namespace {
constexpr double kDeg = M_PI / 180.0;
}

SimulatedGyro::SimulatedGyro(const GyroNoiseModel& model, unsigned seed) : model_(model), rng_(seed) {
  bias_ = std::normal_distribution<double>(0.0, model.residual_bias * kDeg)(rng_);
}

std::vector<GyroSample> SimulatedGyro::samples(double t0, double t1, double true_yaw_change) {
  std::vector<GyroSample> out;
  const double period = 1.0 / model_.rate_hz;
  if (!(t1 > t0)) return out;
  if ((t1 - t0) * model_.rate_hz > kMaxSamples) return out;  // a gap, not an interval a gyro covers
  const double rate = true_yaw_change / (t1 - t0);
  // Discrete white noise of a rate gyro sampled at f: sigma = density * sqrt(f).
  std::normal_distribution<double> white(0.0, model_.noise_density * kDeg * std::sqrt(model_.rate_hz));
  std::normal_distribution<double> walk(0.0, model_.bias_random_walk * kDeg * std::sqrt(period));
  for (double t = t0; t < t1; t += period) {
    bias_ += walk(rng_);
    out.push_back({t, rate + bias_ + white(rng_)});
  }
  return out;
}

double SimulatedGyro::integratedYaw(double t0, double t1, double true_yaw_change) {
  const auto s = samples(t0, t1, true_yaw_change);
  if (s.empty()) return 0.0;
  // Each sample holds until the next one; the last until t1.
  double yaw = 0.0;
  for (size_t i = 0; i < s.size(); ++i) yaw += s[i].rate * ((i + 1 < s.size() ? s[i + 1].stamp : t1) - s[i].stamp);
  return yaw;
}

double gyroIncrementVariance(const GyroNoiseModel& model, double dt) {
  const double white = std::pow(model.noise_density * kDeg, 2) * dt;  // angle random walk
  const double bias = std::pow(model.residual_bias * kDeg * dt, 2);    // unknown constant bias
  const double walk = std::pow(model.bias_random_walk * kDeg, 2) * dt * dt * dt / 3.0;
  return white + bias + walk;
}

double SimulatedGyro::integratedVariance(double dt) const { return gyroIncrementVariance(model_, dt); }

}  // namespace mrslam::slam
