// MRPT rawlogs in the "actions + sensory frames" layout: odometry from
// CActionRobotMovement2D, scans from CObservation2DRangeScan, read with MRPT's CRawlog.
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CRawlog.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/system/datetime.h>
#include <zlib.h>

#include <vector>

#include "mrslam/slam/robot_log.h"
#include "mrslam/slam/sensor_mount.h"

namespace mrslam::slam {

namespace {

// The rawlog's uncompressed length, and why its gzip stream ends early (empty when it does not).
std::pair<uint64_t, std::string> uncompressedLength(const std::string& path) {
  gzFile file = gzopen(path.c_str(), "rb");
  if (!file) return {0, "cannot open"};
  std::vector<char> buffer(1 << 16);
  uint64_t total = 0;
  int n = 0;
  while ((n = gzread(file, buffer.data(), static_cast<unsigned>(buffer.size()))) > 0) total += static_cast<uint64_t>(n);
  int code = Z_OK;
  const char* message = gzerror(file, &code);
  const std::string error = (n < 0 || (code != Z_OK && code != Z_STREAM_END)) ? std::string(message ? message : "read error") : "";
  gzclose(file);
  return {total, error};
}

}  // namespace

RobotLog readMrptRawlog(const std::string& path) {
  // Read object by object (MRPT's own loader stops quietly at a truncated object): a file that
  // ends inside an object, or a gzip stream cut short, is reported as truncated.
  const auto [length, gzip_error] = uncompressedLength(path);
  mrpt::obs::CRawlog rawlog;
  std::string truncated = gzip_error;
  try {
    mrpt::io::CFileGZInputStream stream(path);
    auto archive = mrpt::serialization::archiveFrom(stream);
    for (;;) {
      const uint64_t before = stream.getPosition();
      mrpt::serialization::CSerializable::Ptr object;
      try {
        object = archive.ReadObject();
      } catch (const mrpt::serialization::CExceptionEOF&) {
        if (before < length && truncated.empty()) truncated = "ends inside an object";
        break;
      }
      if (auto actions = std::dynamic_pointer_cast<mrpt::obs::CActionCollection>(object)) rawlog.insert(*actions);
      else if (auto frame = std::dynamic_pointer_cast<mrpt::obs::CSensoryFrame>(object)) rawlog.insert(*frame);
      else if (auto observation = std::dynamic_pointer_cast<mrpt::obs::CObservation>(object)) rawlog.insert(observation);
    }
  } catch (const std::exception& e) {
    if (rawlog.size() == 0) throw LogError(path + ": cannot read rawlog (" + std::string(e.what()).substr(0, 200) + ")");
    if (truncated.empty()) truncated = std::string(e.what()).substr(0, 120);
  }
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
      // The laser's mounting from its full 3D pose (sensor_mount.h): one upside down (roll 180
      // degrees) lists its beams the other way round, which the yaw alone would mirror.
      std::string problem;
      const Eigen::Matrix3d rotation = obs->sensorPose.getRotationMatrix().asEigen();
      const auto mount = laserMount(Eigen::Quaterniond(rotation), obs->sensorPose.x(), obs->sensorPose.y(), &problem);
      if (!mount) throw LogError(path + ": entry " + std::to_string(i) + ": " + problem);
      if (mount->upside_down) scan = uprightScan(std::move(scan));
      if (!laser_pose_set) {
        log.laser_in_base = mount->pose;
        laser_pose_set = true;
      }
      if (!log.records.empty()) record.odometry = since_scan;
      since_scan = Pose2D{};
      log.records.push_back(std::move(record));
    }
  }
  if (!truncated.empty())
    log.warnings.push_back(path + ": input ends early after " + std::to_string(rawlog.size()) + " entries (" + truncated +
                           "): the rawlog is truncated or corrupt");
  if (log.records.empty()) throw LogError(path + ": no 2D range scan in rawlog");
  return log;
}

}  // namespace mrslam::slam
