// Whether a gyro's turns agree with the wheel odometry's, in sign and in scale.
//
// A gyro whose sign is wrong (a frame that tf gets wrong, a driver with another handedness) or
// whose unit is (degrees per second published as radians) is read as the robot turning the
// other way, or 57 times as far, and the filter trusts it over the scans' search window: on the
// Intel excerpt a gyro of the wrong sign bent the map by 20 degrees (5.1 m), and nothing said
// so. Wheel odometry slips, but it does not turn the wrong way: over a few clear turns the
// median of gyro / odometry tells a working gyro (about 1) from a wrong one (-1, 57).
#pragma once

#include <deque>
#include <string>

namespace mrslam::slam {

struct GyroCheckParams {
  int turns = 8;            // clear turns before a verdict (0: never checked)
  double min_turn = 0.087;  // rad the odometry must turn between two scans to count (5 degrees)
  double max_ratio = 2.0;   // the median gyro / odometry turn must lie within [1 / this, this]
};

class GyroCheck {
 public:
  explicit GyroCheck(const GyroCheckParams& params) : params_(params) {}
  // One step's turn by the odometry and by the gyro (rad). Returns true on the step at which
  // the gyro is refused; it stays refused for the run.
  bool observe(double odometry_turn, double gyro_turn);
  bool refused() const { return !problem_.empty(); }
  const std::string& problem() const { return problem_; }  // why the gyro is refused
  void reset() { ratios_.clear(), problem_.clear(); }

 private:
  GyroCheckParams params_;
  std::deque<double> ratios_;  // the last 2 x turns clear turns' gyro / odometry
  std::string problem_;
};

}  // namespace mrslam::slam
