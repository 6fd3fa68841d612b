#include "mrslam/slam/ekf2d.h"

#include <Eigen/Dense>

namespace mrslam::slam {

Ekf2D::Ekf2D(const MotionNoise& noise) : noise_(noise) {}

void Ekf2D::reset(const Pose2D& pose, const Eigen::Matrix3d& covariance) {
  pose_ = pose;
  cov_ = covariance;
  can_refine_control_ = false;
}

Eigen::Matrix3d Ekf2D::motionCovariance(const Pose2D& u) const {
  const double d = std::hypot(u.x, u.y), r = std::abs(u.yaw);
  const double st = noise_.floor_trans + noise_.trans_per_trans * d + noise_.trans_per_rot * r;
  const double sr = noise_.floor_rot + noise_.rot_per_trans * d + noise_.rot_per_rot * r;
  return Eigen::Vector3d(st * st, st * st, sr * sr).asDiagonal();
}

void Ekf2D::predict(const Pose2D& u) {
  prior_pose_ = pose_;
  prior_cov_ = cov_;
  control_ = u;
  control_cov_ = motionCovariance(u);
  can_refine_control_ = true;
  propagate();
}

void Ekf2D::propagate() {
  const double c = std::cos(prior_pose_.yaw), s = std::sin(prior_pose_.yaw);
  const Pose2D& u = control_;
  Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
  F(0, 2) = -s * u.x - c * u.y;
  F(1, 2) = c * u.x - s * u.y;
  Eigen::Matrix3d G = Eigen::Matrix3d::Identity();
  G(0, 0) = c, G(0, 1) = -s, G(1, 0) = s, G(1, 1) = c;
  pose_ = prior_pose_.compose(u);
  cov_ = F * prior_cov_ * F.transpose() + G * control_cov_ * G.transpose();
}

bool Ekf2D::updateYawIncrement(double yaw_increment, double variance) {
  if (!can_refine_control_ || !std::isfinite(yaw_increment) || !(variance > 0)) return false;
  const double innovation = Pose2D::normalizeAngle(yaw_increment - control_.yaw);
  const double S = control_cov_(2, 2) + variance;
  last_d2_ = innovation * innovation / S;
  if (last_d2_ > kGate1) return false;
  const Eigen::Vector3d K = control_cov_.col(2) / S;
  control_.x += K(0) * innovation;
  control_.y += K(1) * innovation;
  control_.yaw = Pose2D::normalizeAngle(control_.yaw + K(2) * innovation);
  control_cov_ -= K * control_cov_.row(2);
  propagate();
  can_refine_control_ = false;  // one gyro update per prediction (RobotSlam sums the readings)
  return true;
}

bool Ekf2D::updatePose(const Pose2D& z, const Eigen::Matrix3d& R) {
  if (!std::isfinite(z.x) || !std::isfinite(z.y) || !std::isfinite(z.yaw) || !R.allFinite()) return false;
  const Eigen::Vector3d y(z.x - pose_.x, z.y - pose_.y, Pose2D::normalizeAngle(z.yaw - pose_.yaw));
  const Eigen::Matrix3d S = cov_ + R;
  const Eigen::LDLT<Eigen::Matrix3d> S_ldlt(S);
  if (S_ldlt.info() != Eigen::Success) return false;
  last_d2_ = y.dot(S_ldlt.solve(y));
  if (!(last_d2_ <= kGate3)) return false;
  const Eigen::Matrix3d K = cov_ * S.inverse();
  const Eigen::Vector3d dx = K * y;
  pose_ = {pose_.x + dx(0), pose_.y + dx(1), Pose2D::normalizeAngle(pose_.yaw + dx(2))};
  // Joseph form keeps the covariance symmetric and positive.
  const Eigen::Matrix3d I_K = Eigen::Matrix3d::Identity() - K;
  cov_ = I_K * cov_ * I_K.transpose() + K * R * K.transpose();
  can_refine_control_ = false;
  return true;
}

}  // namespace mrslam::slam
