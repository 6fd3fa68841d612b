// The paper's cascaded EKF as the local tracker of one robot: wheel odometry predicts, a gyro
// corrects the yaw increment, ICP against a local map of recent key scans corrects the pose.
// Its wide basin: when the prediction is uncertain (poor odometry, scans far apart) or the
// odometry increment is long enough to be a jump, a correlative search over a window of poses
// seeds ICP (the window never narrower than seed_min_yaw, the prior around the prediction
// tighter along the direction driven than across it); a doubted increment is searched around
// both the odometry's prediction and the previous pose, and the better match decides whether
// the robot moved; an increment the scan fits clearly better driven backwards is reversed
// (odometry that reports no sign).
#pragma once

#include <deque>
#include <memory>
#include <optional>

#include "mrslam/slam/correlative_matcher.h"
#include "mrslam/slam/front_end.h"
#include "mrslam/slam/odometry_calibration.h"

namespace mrslam::slam {

class LocalTracker {
 public:
  LocalTracker(const RobotSlamParams& params, const Pose2D& laser_in_base);

  void reset();
  void addOdometry(const Pose2D& increment);
  void addGyro(double yaw_increment, double variance);
  void setTimeUsable(bool usable) { time_usable_ = usable; }
  void setOdometryAvailable(bool available) { odometry_available_ = available; }
  // One scan through the cascade; the local map takes it as a key scan when it moved enough.
  ScanStep track(const LaserScan& scan);

  const Ekf2D& filter() const { return ekf_; }
  const Pose2D& laserInBase() const { return laser_in_base_; }
  size_t scansTracked() const { return scans_; }
  const OdometryCalibration& calibration() const { return calibration_; }
  // Frees the seed search's grids (built again from the local map when next needed).
  void releaseSearchGrids() {
    seed_matcher_.reset();
    seed_grid_.reset();
  }

 private:
  // The seed's prior around a prediction: how far odometry itself errs over the increment.
  struct SeedPrior {
    double xy = 0;         // m: across the direction driven (in every direction when along is 0)
    double yaw = 0;        // rad
    double along = 0;      // m: along the direction driven (0: none)
    double direction = 0;  // rad: the direction driven, in the tracker's frame
    SeedPrior isotropic() const { return {xy, yaw, 0.0, 0.0}; }
  };

  // The constant-velocity prediction's added uncertainty and prior when there is no odometry.
  Eigen::Matrix3d noOdometryCovariance() const;
  SeedPrior noOdometryPrior() const;
  // The local map's likelihood grid, rebuilt when the local map changed.
  const LikelihoodGrid& seedGrid();
  // The best correlative match in a window around `center`, on the local map. With `rival_of`,
  // the best one at least 1 m / 5 degrees from that pose scoring `rival_min_score` (its rival).
  CorrelativeMatch seedMatch(const Points2& points, const Pose2D& center, double xy, double yaw, const SeedPrior& prior,
                             const Pose2D* rival_of = nullptr, double rival_min_score = 0);
  bool doubted(const Pose2D& increment, double stamp) const;
  // The prior of a seed for the increment `u` driven from `before`.
  SeedPrior seedPrior(const Pose2D& before, const Pose2D& u) const;
  // The scan searched for at every heading within `max_xy` of `guess`, taken only where it fits
  // well and well ahead of any other pose (seed.missed_turn_*). `doubted` says whether it fitted
  // clearly better than at `guess` (where it fits `guess_fit`) at a heading far from it, and was
  // not taken.
  std::optional<CorrelativeMatch> missedTurn(const Points2& points, const Pose2D& guess, double max_xy, const SeedPrior& prior,
                                             double guess_fit, bool& doubted);
  // Whether ICP, weak on its own, landed where the seed put the scan.
  bool seedConfirms(const ScanStep& step) const;
  // Whether a seed ICP did not confirm still scored clearly above the prediction.
  bool seedStandsAlone(const ScanStep& step) const;
  // The run's typical increment: a high quantile of the last moving strides' lengths (0 before any).
  double typicalStride() const;
  void rememberStride(const Pose2D& u);
  // Whether the scan's (thinned) points fit the local map clearly better at `match` than at
  // `prediction`.
  bool scanPrefers(const Points2& points, const Pose2D& match, const Pose2D& prediction);
  // Where the robot is had it driven the increment `u` backwards from `before`, when the scan's
  // (thinned) points say so clearly; nothing otherwise.
  std::optional<Pose2D> reversedPrediction(const Points2& points, const Pose2D& before, const Pose2D& u);

  RobotSlamParams params_;
  Pose2D laser_in_base_;
  Ekf2D ekf_;
  ScanToMapMatcher matcher_;
  OdometryCalibration calibration_;
  std::shared_ptr<LikelihoodGrid> seed_grid_;          // the local map's, rebuilt in place when it changed...
  std::unique_ptr<CorrelativeMatcher> seed_matcher_;  // ...and searched by this
  uint64_t seed_version_ = 0;
  Pose2D odometry_;  // accumulated since the last scan
  double gyro_yaw_ = 0, gyro_var_ = 0;
  bool have_gyro_ = false;
  GyroCheck gyro_check_;
  bool time_usable_ = true;
  bool odometry_available_ = true;
  Pose2D last_motion_;  // the tracked motion of the last scan: the prediction without odometry
  size_t searches_given_up_ = 0;  // seed searches that hit kMaxEvaluations
  std::deque<double> strides_;  // lengths of the last moving increments, for doubted() without time
  size_t scans_ = 0;
  double last_stamp_ = 0;
};

}  // namespace mrslam::slam
