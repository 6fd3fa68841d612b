// Online calibration of wheel odometry's systematic errors, learnt from the scan matcher: a
// scale of the translation (tyre radius) and a yaw drift per metre driven (wheel base,
// unequal tyres). Real odometry errs systematically (the Intel log's turns by 3.5 degrees per
// metre; several logs overstate distance by 4-6 %), and a prediction corrected for it keeps the
// truth inside the scan matcher's window when scans are far apart.
//
// Recursive least squares with exponential forgetting over the steps the scan matcher matched
// well (pairing most points, or, with from_seeds, confirmed by the correlative seed): forward
// distance measured against odometry's (through the origin), and the yaw the match added
// against the distance driven. Corrections apply once enough has been driven, and stay within
// bounds (a broken estimate cannot make the prediction absurd). The drift bends the way driven,
// so the corrected increment also turns its chord by half the drift.
#pragma once

#include "mrslam/grid.h"

namespace mrslam::slam {

struct OdometryCalibrationParams {
  bool enabled = true;
  double forgetting = 0.995;     // per learnt step
  double min_distance = 10.0;    // m driven (in learnt steps) before corrections apply
  double max_scale_error = 0.15; // |scale - 1| at most
  double max_yaw_per_m = 0.1;    // rad per m at most (5.7 degrees)
  // Also learn from matches ICP pairs few points of but the correlative seed agrees with
  // (scans metres apart); otherwise only from matches pairing most points.
  bool from_seeds = true;
};

class OdometryCalibration {
 public:
  explicit OdometryCalibration(const OdometryCalibrationParams& params = OdometryCalibrationParams{}) : params_(params) {}

  // The increment corrected by what has been learnt (unchanged until enough was driven).
  Pose2D correct(const Pose2D& odometry) const;
  // One step the scan matcher matched well: `odometry` raw, `measured` the increment the
  // matched poses say.
  void learn(const Pose2D& odometry, const Pose2D& measured);
  double scale() const;
  double yawPerMetre() const;
  void reset() { *this = OdometryCalibration(params_); }

 private:
  OdometryCalibrationParams params_;
  double driven_ = 0;                  // m, in learnt steps
  double sxx_ = 0, sxm_ = 0;           // forward: odometry^2, odometry * measured
  double sdd_ = 0, sdr_ = 0;           // yaw: distance^2, distance * (measured - odometry yaw)
};

}  // namespace mrslam::slam
