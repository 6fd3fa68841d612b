// The cascaded EKF of one robot (Saeedi et al. 2011, single-robot SLAM): state (x, y, yaw)
// of base_link in the robot's map frame and its covariance. Wheel odometry is the control
// input of the prediction; a MEMS gyro and laser scan matching are measurements. The
// cascade per scan is: predict(odometry) -> updateYawIncrement(gyro) -> updatePose(scan match).
#pragma once

#include <Eigen/Core>

#include "mrslam/grid.h"

namespace mrslam::slam {

struct MotionNoise {
  // Standard deviations proportional to the motion (a classic odometry model):
  double trans_per_trans = 0.2;   // m of translation error per m travelled
  double trans_per_rot = 0.05;   // m per rad turned
  double rot_per_trans = 0.2;     // rad per m travelled
  double rot_per_rot = 0.3;       // rad per rad turned
  double floor_trans = 0.02;      // m, per prediction, so the filter never becomes overconfident
  double floor_rot = 0.01;        // rad, per prediction
};

class Ekf2D {
 public:
  // Chi-square bounds used for gating (99.9 %): 3 degrees of freedom, 1 degree of freedom.
  static constexpr double kGate3 = 16.27, kGate1 = 10.83;

  explicit Ekf2D(const MotionNoise& noise = MotionNoise{});

  void reset(const Pose2D& pose, const Eigen::Matrix3d& covariance);

  // Prediction with an odometry increment u (in the robot frame at the previous state):
  // x' = x ⊕ u, P' = F P F^T + G Q(u) G^T.
  void predict(const Pose2D& odometry_increment);

  // IMU update on the yaw change since the last predict(), e.g. an integrated gyro. It is a
  // measurement of the control's yaw component: the increment is corrected by a Kalman
  // update of (u, Q) and the prediction redone from the pre-prediction state (exact for the
  // state augmented with the control). Must follow predict() before any other update.
  // Returns false when gated out (Mahalanobis distance above kGate1) or not applicable.
  bool updateYawIncrement(double yaw_increment, double variance);

  // Absolute pose measurement (scan matching against the local map): H = I.
  // Returns false when gated out (Mahalanobis distance above kGate3).
  bool updatePose(const Pose2D& measured, const Eigen::Matrix3d& covariance);

  const Pose2D& pose() const { return pose_; }
  const Eigen::Matrix3d& covariance() const { return cov_; }
  // Squared Mahalanobis distance of the last update's innovation (for diagnostics).
  double lastMahalanobis2() const { return last_d2_; }

  // Motion noise covariance of an increment (exposed for tests).
  Eigen::Matrix3d motionCovariance(const Pose2D& u) const;

 private:
  void propagate();

  MotionNoise noise_;
  Pose2D pose_;
  Eigen::Matrix3d cov_ = Eigen::Matrix3d::Zero();
  // Last prediction, kept so the IMU update can redo it with a corrected control.
  bool can_refine_control_ = false;
  Pose2D prior_pose_, control_;
  Eigen::Matrix3d prior_cov_ = Eigen::Matrix3d::Zero(), control_cov_ = Eigen::Matrix3d::Zero();
  double last_d2_ = 0.0;
};

}  // namespace mrslam::slam
