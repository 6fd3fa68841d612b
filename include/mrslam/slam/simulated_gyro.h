// SIMULATED MEMS gyro. None of the real logs has an IMU, so where one is wanted its yaw rate
// is simulated from the log's reference trajectory (the yaw change between two scans spread
// evenly over the interval) plus the noise of a MEMS rate gyro with the typical datasheet
// figures of an Analog Devices ADXRS453 (rate noise density 0.015 deg/s/sqrt(Hz), in-run bias
// stability 16 deg/h), after a standstill bias calibration at start-up. Everything
// that uses it says "simulated" (topic imu_simulated, --simulated-imu, result labels).
#pragma once

#include <random>
#include <vector>

namespace mrslam::slam {

struct GyroNoiseModel {
  double rate_hz = 100.0;                 // sample rate
  double noise_density = 0.015;           // deg/s/sqrt(Hz): white rate noise (angle random walk)
  double residual_bias = 0.005;           // deg/s, 1 sigma: bias left after the standstill calibration
                                          // (about the part's 16 deg/h in-run bias stability)
  double bias_random_walk = 0.0001;       // deg/s/sqrt(s): slow bias wander over a run
};

struct GyroSample {
  double stamp;  // s
  double rate;   // rad/s about the robot's z axis
};

// Variance of the yaw change a gyro with this noise model integrates over `dt` seconds
// (white noise, the unknown residual bias, the bias wander); the filter's model for a real
// gyro as well as for the simulated one.
double gyroIncrementVariance(const GyroNoiseModel& model, double dt);

class SimulatedGyro {
 public:
  SimulatedGyro(const GyroNoiseModel& model, unsigned seed);

  // Samples in [t0, t1) for a robot whose yaw changes by `true_yaw_change` over the interval;
  // none when that would be more than kMaxSamples (a gap in the log, not an interval to cover).
  static constexpr double kMaxSamples = 1e5;
  std::vector<GyroSample> samples(double t0, double t1, double true_yaw_change);
  // The yaw change the gyro reports over [t0, t1) (its samples integrated).
  double integratedYaw(double t0, double t1, double true_yaw_change);
  // The variance a filter should give that integrated yaw change over `dt` seconds.
  double integratedVariance(double dt) const;
  double bias() const { return bias_; }  // rad/s, current

 private:
  GyroNoiseModel model_;
  std::mt19937 rng_;
  double bias_;
};

}  // namespace mrslam::slam
