// MRPT rawlogs in the "actions + sensory frames" layout: odometry from
// CActionRobotMovement2D, scans from CObservation2DRangeScan, read with MRPT's CRawlog.
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CRawlog.h>
#include <mrpt/system/datetime.h>

#include "mrslam/slam/robot_log.h"

namespace mrslam::slam {

RobotLog readMrptRawlog(const std::string& path) {
  mrpt::obs::CRawlog rawlog;
  bool loaded = false;
  try {
    loaded = rawlog.loadFromRawLogFile(path);
  } catch (const std::exception& e) {
    throw LogError(path + ": cannot read rawlog (" + std::string(e.what()).substr(0, 200) + ")");
  }
  if (!loaded) throw LogError(path + ": cannot open or parse rawlog");
  RobotLog log;
  log.path = path;
  log.format = "rawlog";
  Pose2D since_scan;
  bool laser_pose_set = false;
  for (size_t i = 0; i < rawlog.size(); ++i) {
    if (rawlog.getType(i) == mrpt::obs::CRawlog::etActionCollection) {
      const auto actions = rawlog.getAsAction(i);
      if (const auto move = actions->getBestMovementEstimation()) {
        const mrpt::poses::CPose2D d = move->poseChange->getMeanVal();
        since_scan = since_scan.compose(Pose2D{d.x(), d.y(), d.phi()});
      }
    } else if (rawlog.getType(i) == mrpt::obs::CRawlog::etSensoryFrame) {
      const auto frame = rawlog.getAsObservations(i);
      const auto obs = frame->getObservationByClass<mrpt::obs::CObservation2DRangeScan>();
      if (!obs) continue;
      LogRecord record;
      LaserScan& scan = record.scan;
      const size_t n = obs->getScanSize();
      if (n < 2) {
        log.warnings.push_back(path + ": entry " + std::to_string(i) + ": scan with fewer than 2 rays skipped");
        continue;
      }
      scan.stamp = mrpt::Clock::toDouble(obs->timestamp);
      const double step = obs->aperture / (n - 1);
      scan.angle_increment = obs->rightToLeft ? step : -step;
      scan.angle_min = obs->rightToLeft ? -obs->aperture / 2 : obs->aperture / 2;
      scan.range_min = 0.01;
      scan.range_max = obs->maxRange;
      scan.ranges.resize(n);
      for (size_t k = 0; k < n; ++k)
        scan.ranges[k] = obs->getScanRangeValidity(k) ? obs->getScanRange(k) : std::numeric_limits<float>::quiet_NaN();
      if (!laser_pose_set) {
        log.laser_in_base = {obs->sensorPose.x(), obs->sensorPose.y(), obs->sensorPose.yaw()};
        laser_pose_set = true;
      }
      if (!log.records.empty()) record.odometry = since_scan;
      since_scan = Pose2D{};
      log.records.push_back(std::move(record));
    }
  }
  if (log.records.empty()) throw LogError(path + ": no 2D range scan in rawlog");
  return log;
}

}  // namespace mrslam::slam
