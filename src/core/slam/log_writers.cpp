#include "mrslam/slam/log_writers.h"

#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <memory>

namespace mrslam::slam {

RobotLog fromScan(const RobotLog& log, size_t first) {
  if (first >= log.records.size())
    throw LogError(log.path + ": cannot start at scan " + std::to_string(first) + " of " + std::to_string(log.records.size()));
  RobotLog out = log;
  out.records.erase(out.records.begin(), out.records.begin() + static_cast<std::ptrdiff_t>(first));
  out.records.front().odometry = Pose2D{};  // the robot starts here: no motion before it
  return out;
}

RobotLog decimate(const RobotLog& log, int every, int phase) {
  if (every < 1) throw LogError(log.path + ": decimation must keep every k-th scan with k >= 1");
  if (phase < 0 || phase >= every) throw LogError(log.path + ": decimation phase must be in [0, k)");
  RobotLog out = log;
  out.records.clear();
  Pose2D since_kept;
  for (size_t k = 0; k < log.records.size(); ++k) {
    since_kept = since_kept.compose(log.records[k].odometry);
    if (k < static_cast<size_t>(phase) || (k - phase) % every != 0) continue;
    LogRecord record = log.records[k];
    record.odometry = out.records.empty() ? Pose2D{} : since_kept;
    since_kept = Pose2D{};
    out.records.push_back(std::move(record));
  }
  return out;
}

namespace {

struct FileCloser {
  void operator()(FILE* f) const { if (f) std::fclose(f); }
};

}  // namespace

void writeCarmenLog(const RobotLog& log, const std::string& path) {
  std::unique_ptr<FILE, FileCloser> file(std::fopen(path.c_str(), "w"));
  if (!file) throw LogError(path + ": cannot write");
  FILE* f = file.get();
  std::fprintf(f, "# written by mrslam from %s (%zu scans)\n", log.path.c_str(), log.records.size());
  std::fprintf(f, "PARAM robot_frontlaser_offset %.6f nohost 0\n", log.laser_in_base.x);
  // "No return" is written as the laser's maximum range, and this line says which range that is:
  // without it a reader takes its default (50 m) and reads a short laser's no-returns as walls at
  // its maximum range. One line for the log: the largest maximum of its scans.
  double range_max = 0.0;
  for (const LogRecord& r : log.records) range_max = std::max(range_max, r.scan.range_max);
  const bool declared = plausibleCarmenLaserMax(range_max);
  if (declared) std::fprintf(f, "PARAM robot_front_laser_max %.3f nohost 0\n", range_max);
  Pose2D anchor;
  for (size_t k = 0; k < log.records.size(); ++k) {
    const LogRecord& r = log.records[k];
    const double t = r.scan.stamp;
    const double odom_t = t != 0.0 ? t : 1e-6;  // an ODOM time stamp of 0 marks a re-anchor
    // A laser-only log stays one: zero-motion ODOM lines would say the robot stood at every scan.
    if (k > 0 && log.has_odometry) {  // the odometry since the previous scan, relative to its anchor line
      const Pose2D reached = anchor.compose(r.odometry);
      std::fprintf(f, "ODOM %.6f %.6f %.6f 0 0 0 %.6f nohost %.6f\n", reached.x, reached.y, reached.yaw, odom_t, t);
    }
    const Pose2D& p = r.has_reference ? r.reference : Pose2D{};
    std::fprintf(f, "FLASER %zu", r.scan.ranges.size());
    // A no-return must read back as one: at or beyond the declared maximum.
    const double limit = declared ? range_max : r.scan.range_max;
    for (float range : r.scan.ranges) {
      const bool rewrite = !std::isfinite(range) || (isNoReturn(r.scan, range) && range < limit);
      std::fprintf(f, " %.3f", rewrite ? limit : range);
    }
    std::fprintf(f, " %.6f %.6f %.6f %.6f %.6f %.6f %.6f nohost %.6f\n", p.x, p.y, p.yaw, p.x, p.y, p.yaw, t, t);
    anchor = p;
    if (log.has_odometry) std::fprintf(f, "ODOM %.6f %.6f %.6f 0 0 0 0 nohost %.6f\n", anchor.x, anchor.y, anchor.yaw, t);
  }
  if (std::ferror(f) || std::fflush(f) != 0) throw LogError(path + ": write failed");
  if (std::fclose(file.release()) != 0) throw LogError(path + ": write failed");
}

void writeMrptRawlog(const RobotLog& log, const std::string& path) {
  try {
    mrpt::io::CFileGZOutputStream stream(path);
    auto archive = mrpt::serialization::archiveFrom(stream);
    for (size_t k = 0; k < log.records.size(); ++k) {
      const LogRecord& r = log.records[k];
      const mrpt::Clock::time_point stamp = mrpt::Clock::fromDouble(r.scan.stamp);
      mrpt::obs::CActionCollection actions;
      mrpt::obs::CActionRobotMovement2D move;
      move.computeFromOdometry(mrpt::poses::CPose2D(r.odometry.x, r.odometry.y, r.odometry.yaw),
                               mrpt::obs::CActionRobotMovement2D::TMotionModelOptions());
      move.timestamp = stamp;
      actions.insert(move);
      archive << actions;

      const LaserScan& s = r.scan;
      auto scan = std::make_shared<mrpt::obs::CObservation2DRangeScan>();
      const size_t n = s.ranges.size();
      const double span = s.angle_increment * (n > 0 ? n - 1 : 0);
      // MRPT spreads the rays over an aperture centred on the sensor's x axis.
      scan->aperture = static_cast<float>(std::abs(span));
      scan->rightToLeft = span > 0;
      scan->maxRange = static_cast<float>(s.range_max);
      scan->resizeScan(n);
      for (size_t i = 0; i < n; ++i) {
        const float range = s.ranges[i];
        const bool valid = isReturn(s, range);
        scan->setScanRange(i, valid ? range : 0.0f);
        scan->setScanRangeValidity(i, valid);
      }
      const Pose2D sensor = log.laser_in_base.compose(Pose2D{0, 0, s.angle_min + span / 2});
      scan->sensorPose = mrpt::poses::CPose3D(sensor.x, sensor.y, 0, sensor.yaw, 0, 0);
      scan->timestamp = stamp;
      scan->sensorLabel = "LASER";
      mrpt::obs::CSensoryFrame frame;
      frame.insert(scan);
      archive << frame;
    }
  } catch (const std::exception& e) {
    throw LogError(path + ": cannot write rawlog (" + std::string(e.what()).substr(0, 200) + ")");
  }
}

}  // namespace mrslam::slam
