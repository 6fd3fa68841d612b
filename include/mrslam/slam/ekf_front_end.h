// The paper's front end alone (Saeedi et al. 2011, single-robot SLAM): the cascaded EKF
// (local_tracker.h) and the occupancy grid built along its filtered poses. No loop closure:
// kept for comparison (--no-loop-closure, loop_closure: false).
#pragma once

#include "mrslam/slam/front_end.h"
#include "mrslam/slam/local_tracker.h"

namespace mrslam::slam {

class EkfFrontEnd : public FrontEnd {
 public:
  EkfFrontEnd(const RobotSlamParams& params, const Pose2D& laser_in_base);

  void addOdometry(const Pose2D& increment) override { tracker_.addOdometry(increment); }
  void addGyro(double yaw_increment, double variance) override { tracker_.addGyro(yaw_increment, variance); }
  ScanStep processScan(const LaserScan& scan) override;
  void reset() override;
  void setTimeUsable(bool usable) override { tracker_.setTimeUsable(usable); }
  void setOdometryAvailable(bool available) override { tracker_.setOdometryAvailable(available); }

  Pose2D pose() const override { return tracker_.filter().pose(); }
  Eigen::Matrix3d covariance() const override { return tracker_.filter().covariance(); }
  std::vector<Pose2D> trajectory() const override { return trajectory_; }
  std::vector<MapPart> mapParts() const override {
    return {{std::make_shared<const OccupancyGrid>(mapper_.toGrid()), Pose2D{}, nullptr}};
  }
  uint64_t mapVersion() const override { return mapper_.version(); }
  FrontEndStats stats() const override { return stats_; }
  std::string name() const override { return "ekf"; }

 private:
  RobotSlamParams params_;
  LocalTracker tracker_;
  GridMapper mapper_;
  std::vector<Pose2D> trajectory_;
  FrontEndStats stats_;
  bool have_map_pose_ = false;
  Pose2D last_map_pose_;
};

// Adds what one scan did to the run's counts.
void countStep(const ScanStep& step, FrontEndStats& stats);

}  // namespace mrslam::slam
