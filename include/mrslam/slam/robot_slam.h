// One robot's front end, exactly as the nodelets and mrslam_slam_log run it: the cascaded
// EKF (odometry -> gyro -> scan matching) and the grid map built along the filtered poses.
#pragma once

#include <string>

#include "mrslam/slam/ekf2d.h"
#include "mrslam/slam/grid_mapper.h"
#include "mrslam/slam/laser_scan.h"
#include "mrslam/slam/scan_matcher.h"

namespace mrslam::slam {

struct RobotSlamParams {
  MotionNoise motion;
  ScanMatcherParams matcher;
  GridMapperParams grid;
  bool use_scan_matching = true;
  bool use_imu = true;            // gyro updates are used when they arrive
  double map_update_distance = 0.0;  // m moved before a scan is inserted into the grid (0: every scan)
  double map_update_angle = 0.0;     // rad turned before a scan is inserted into the grid
  // An odometry increment longer than max_odometry_jump + max_odometry_speed * (time since the
  // previous scan) is a jump (wheel slip, driver restart), not motion: it is not trusted and the
  // scan matcher starts from the previous pose. The time term keeps a legitimate increment
  // across skipped scans from looking like a jump.
  double max_odometry_jump = 0.5;   // m
  double max_odometry_speed = 2.0;  // m/s
};

struct ScanStep {
  bool used = false;            // false: the scan was rejected (reason says why)
  std::string reason;
  bool matched = false;         // scan matching accepted by the EKF
  bool gated = false;           // scan match rejected by the Mahalanobis gate
  bool imu_used = false;
  bool odometry_jump = false;
  ScanMatch match;
};

class RobotSlam {
 public:
  RobotSlam(const RobotSlamParams& params, const Pose2D& laser_in_base);

  // Odometry increment (robot frame) since the previous call; accumulated until the next scan.
  void addOdometry(const Pose2D& increment);
  // Gyro yaw change (rad) over an interval and its variance; accumulated until the next scan.
  void addGyro(double yaw_increment, double variance);
  // Runs the cascade on one scan and inserts it into the map.
  ScanStep processScan(const LaserScan& scan);
  // Forgets everything (bag restarted, time went backwards).
  void reset();

  const Ekf2D& filter() const { return ekf_; }
  const GridMapper& map() const { return mapper_; }
  size_t scansProcessed() const { return scans_; }
  const RobotSlamParams& params() const { return params_; }

 private:
  RobotSlamParams params_;
  Pose2D laser_in_base_;
  Ekf2D ekf_;
  ScanToMapMatcher matcher_;
  GridMapper mapper_;
  Pose2D odometry_;             // accumulated since the last scan
  double gyro_yaw_ = 0, gyro_var_ = 0;
  bool have_gyro_ = false;
  size_t scans_ = 0;
  bool have_map_pose_ = false;
  double last_stamp_ = 0;
  Pose2D last_map_pose_;
};

}  // namespace mrslam::slam
