// Sensors mounted otherwise than upright and facing forward: the mounting comes from tf's full
// rotation (sensor_mount.h), on real Intel scans.
#include <gtest/gtest.h>

#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CRawlog.h>
#include <mrpt/obs/CSensoryFrame.h>

#include <algorithm>
#include <cmath>

#include "mrslam/slam/sensor_mount.h"
#include "test_logs.h"

namespace mrslam::slam {
namespace {

Eigen::Quaterniond about(const Eigen::Vector3d& axis, double angle) { return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis)); }

// What an upside-down laser reports for the beams of `scan` (as mrslam_log_to_bag
// --turned-sensors writes it): the ranges in reverse order, from minus the last beam's angle.
LaserScan turnedOver(const LaserScan& scan) {
  LaserScan turned = scan;
  turned.angle_min = static_cast<float>(-(scan.angle_min + scan.angle_increment * (scan.ranges.size() - 1)));
  std::reverse(turned.ranges.begin(), turned.ranges.end());
  return turned;
}

TEST(SensorMount, AnUpsideDownLaserSeesWhatAnUprightOneSees) {
  const auto& log = test::intelLog();
  const Pose2D& laser = log.laser_in_base;
  // Mounted upside down and turned 30 degrees, so that a heading read wrongly would show too.
  const Pose2D mounted{laser.x + 0.1, laser.y - 0.05, laser.yaw + 0.5};
  const Eigen::Quaterniond rotation = about(Eigen::Vector3d::UnitZ(), mounted.yaw) * about(Eigen::Vector3d::UnitX(), M_PI);
  std::string problem;
  const auto mount = laserMount(rotation, mounted.x, mounted.y, &problem);
  ASSERT_TRUE(mount) << problem;
  EXPECT_TRUE(mount->upside_down);
  EXPECT_NEAR(mount->pose.x, mounted.x, 1e-12);
  EXPECT_NEAR(mount->pose.y, mounted.y, 1e-12);
  EXPECT_NEAR(Pose2D::normalizeAngle(mount->pose.yaw - mounted.yaw), 0.0, 1e-12);
  double worst = 0, mirrored_worst = 0;
  size_t compared = 0;
  for (size_t i = 0; i < log.records.size(); i += 50) {
    const LaserScan& scan = log.records[i].scan;
    const auto truth = scanPoints(scan, mounted);
    const LaserScan turned = turnedOver(scan);
    const auto read = scanPoints(uprightScan(turned), mount->pose);
    const auto read_as_upright = scanPoints(turned, mount->pose);  // the mounting's yaw alone
    ASSERT_EQ(read.size(), truth.size());
    for (size_t k = 0; k < truth.size(); ++k) {
      // Read upright, the beams come in the upright laser's order; read as they come, the other
      // way round.
      const auto& [x, y] = read[k];
      const auto& [mx, my] = read_as_upright[truth.size() - 1 - k];
      worst = std::max<double>(worst, std::hypot(x - truth[k].first, y - truth[k].second));
      mirrored_worst = std::max<double>(mirrored_worst, std::hypot(mx - truth[k].first, my - truth[k].second));
      ++compared;
    }
  }
  EXPECT_GT(compared, 2000u);
  EXPECT_LT(worst, 1e-4) << "m between a return read from the upside-down laser and the same return read upright";
  EXPECT_GT(mirrored_worst, 1.0) << "m: read as upright, the scans would be mirrored";
}

// MRPT keeps a laser's full 3D pose in the rawlog; the reader took its yaw alone.
TEST(SensorMount, AnUpsideDownLaserInAnMrptRawlogIsReadUpright) {
  const std::string original = test::dataPath("logs/mrpt/2006-01ENE-21-SENA_Telecom_Faculty_one_loop_only.rawlog");
  mrpt::obs::CRawlog rawlog;
  ASSERT_TRUE(rawlog.loadFromRawLogFile(original));
  size_t turned = 0;
  for (size_t i = 0; i < rawlog.size(); ++i) {
    if (rawlog.getType(i) != mrpt::obs::CRawlog::etSensoryFrame) continue;
    const auto obs = rawlog.getAsObservations(i)->getObservationByClass<mrpt::obs::CObservation2DRangeScan>();
    if (!obs) continue;
    // The same beams from the laser rolled 180 degrees about its x axis: listed the other way round.
    const size_t n = obs->getScanSize();
    std::vector<float> ranges(n);
    std::vector<bool> valid(n);
    for (size_t k = 0; k < n; ++k) ranges[k] = obs->getScanRange(k), valid[k] = obs->getScanRangeValidity(k);
    for (size_t k = 0; k < n; ++k) obs->setScanRange(k, ranges[n - 1 - k]), obs->setScanRangeValidity(k, valid[n - 1 - k]);
    const mrpt::poses::CPose3D pose = obs->sensorPose;
    obs->sensorPose.setFromValues(pose.x(), pose.y(), pose.z(), pose.yaw(), pose.pitch(), pose.roll() + M_PI);
    ++turned;
  }
  ASSERT_GT(turned, 200u);
  const std::string path = ::testing::TempDir() + "/upside_down.rawlog";
  ASSERT_TRUE(rawlog.saveToRawLogFile(path));
  const RobotLog upright = readRobotLog(original), upside_down = readRobotLog(path);
  ASSERT_EQ(upside_down.records.size(), upright.records.size());
  EXPECT_NEAR(upside_down.laser_in_base.x, upright.laser_in_base.x, 1e-9);
  EXPECT_NEAR(upside_down.laser_in_base.y, upright.laser_in_base.y, 1e-9);
  EXPECT_NEAR(Pose2D::normalizeAngle(upside_down.laser_in_base.yaw - upright.laser_in_base.yaw), 0.0, 1e-9);
  double worst = 0;
  size_t compared = 0;
  for (size_t i = 0; i < upright.records.size(); ++i) {
    const auto truth = scanPoints(upright.records[i].scan, upright.laser_in_base);
    const auto read = scanPoints(upside_down.records[i].scan, upside_down.laser_in_base);
    ASSERT_EQ(read.size(), truth.size());
    for (size_t k = 0; k < truth.size(); ++k, ++compared)
      worst = std::max<double>(worst, std::hypot(read[k].first - truth[k].first, read[k].second - truth[k].second));
  }
  EXPECT_GT(compared, 10000u);
  EXPECT_LT(worst, 1e-4) << "m between a return of the upside-down laser and the same return of the upright one";
}

TEST(SensorMount, AnUprightLaserKeepsItsScansAsTheyAre) {
  std::string problem;
  // Leaning 10 degrees forward, as a laser tilted towards the floor ahead.
  const auto mount = laserMount(about(Eigen::Vector3d::UnitZ(), -1.0) * about(Eigen::Vector3d::UnitY(), 10 * M_PI / 180), 0.2, 0.0, &problem);
  ASSERT_TRUE(mount) << problem;
  EXPECT_FALSE(mount->upside_down);
  EXPECT_NEAR(mount->pose.yaw, -1.0, 1e-12);
}

TEST(SensorMount, ALaserTiltedTooFarOrNotFiniteIsRefusedByName) {
  std::string problem;
  EXPECT_FALSE(laserMount(about(Eigen::Vector3d::UnitY(), 45 * M_PI / 180), 0, 0, &problem));
  EXPECT_NE(problem.find("tilted 45 degrees"), std::string::npos) << problem;
  problem.clear();
  EXPECT_FALSE(laserMount(about(Eigen::Vector3d::UnitX(), M_PI / 2), 0, 0, &problem));  // scanning a vertical plane
  EXPECT_NE(problem.find("tilted 90 degrees"), std::string::npos) << problem;
  problem.clear();
  EXPECT_FALSE(laserMount(Eigen::Quaterniond(NAN, 0, 0, 1), 0, 0, &problem));
  EXPECT_NE(problem.find("not finite"), std::string::npos) << problem;
  problem.clear();
  EXPECT_FALSE(laserMount(Eigen::Quaterniond(0, 0, 0, 0), 0, 0, &problem));
  EXPECT_NE(problem.find("not finite"), std::string::npos) << problem;
  problem.clear();
  EXPECT_FALSE(laserMount(Eigen::Quaterniond::Identity(), INFINITY, 0, &problem));
  EXPECT_NE(problem.find("not finite"), std::string::npos) << problem;
  // Just within the limit, either side up.
  EXPECT_TRUE(laserMount(about(Eigen::Vector3d::UnitY(), 29 * M_PI / 180), 0, 0, &problem));
  EXPECT_TRUE(laserMount(about(Eigen::Vector3d::UnitY(), M_PI - 29 * M_PI / 180), 0, 0, &problem));
}

TEST(SensorMount, AGyroMountedAnyWayGivesTheRobotsYawRate) {
  const double yaw_rate = 0.37;  // rad/s about the robot's z axis
  // The robot also rolls and pitches a little (a bump): no yaw in that.
  const Eigen::Vector3d turning(0.05, -0.02, yaw_rate);
  for (const Eigen::Quaterniond& mounting :
       {Eigen::Quaterniond::Identity(), about(Eigen::Vector3d::UnitX(), M_PI), about(Eigen::Vector3d::UnitY(), -M_PI / 2),
        about(Eigen::Vector3d::UnitZ(), 2.0) * about(Eigen::Vector3d(1, 2, 3).normalized(), 0.7)}) {
    // What the gyro measures: the robot's angular velocity in the gyro's own frame.
    const Eigen::Vector3d measured = mounting.conjugate() * turning;
    EXPECT_NEAR(baseYawRate(mounting, measured), yaw_rate, 1e-12);
  }
  // A gyro on its side has the turn on its x axis, none on its z axis.
  const Eigen::Vector3d on_side = about(Eigen::Vector3d::UnitY(), -M_PI / 2).conjugate() * turning;
  EXPECT_NEAR(on_side.x(), yaw_rate, 1e-12);
  EXPECT_LT(std::abs(on_side.z()), 0.1);
}

}  // namespace
}  // namespace mrslam::slam
