// GyroCheck (gyro_check.h) on the real logs' odometry, against a perfect gyro (the reference
// poses' turns) and the same gyro with its sign or its unit wrong.
#include <gtest/gtest.h>

#include <cmath>

#include "mrslam/slam/gyro_check.h"
#include "test_logs.h"

namespace mrslam::slam {
namespace {

// Steps until the check refuses a gyro that reports `scale` times the reference's turns, fed
// with the log's raw odometry (-1: never, over the whole log).
long refusedAfter(const RobotLog& log, double scale) {
  GyroCheck check{GyroCheckParams{}};
  const auto odometry = chainOdometry(log);
  for (size_t k = 1; k < log.records.size(); ++k) {
    const double odometry_turn = Pose2D::normalizeAngle(odometry[k].yaw - odometry[k - 1].yaw);
    const double gyro_turn = scale * Pose2D::normalizeAngle(log.records[k].reference.yaw - log.records[k - 1].reference.yaw);
    if (check.observe(odometry_turn, gyro_turn)) return static_cast<long>(k);
  }
  return -1;
}

TEST(GyroCheck, AWorkingGyroIsNeverSetAsideOnAnyLog) {
  for (const RobotLog* log : {&test::intelLog(), &test::acesLog(), &test::freiburg079Log(), &test::freiburg101Log()})
    EXPECT_EQ(refusedAfter(*log, 1.0), -1) << log->records.size() << " scans";
}

TEST(GyroCheck, AGyroOfTheWrongSignOrUnitIsSetAsideEarly) {
  for (const RobotLog* log : {&test::intelLog(), &test::acesLog(), &test::freiburg079Log(), &test::freiburg101Log()})
    for (double scale : {-1.0, 180.0 / M_PI, M_PI / 180.0}) {
      const long after = refusedAfter(*log, scale);
      EXPECT_GT(after, 0) << "scale " << scale;
      EXPECT_LT(after, 200) << "scale " << scale << ": scans before the check refused it";
    }
}

TEST(GyroCheck, SaysWhyAndStaysRefused) {
  GyroCheck check{GyroCheckParams{}};
  bool refused_now = false;
  for (int k = 0; k < 8; ++k) refused_now = check.observe(0.2, -0.2);
  EXPECT_TRUE(refused_now);
  EXPECT_NE(check.problem().find("-1.00 times as far"), std::string::npos) << check.problem();
  for (int k = 0; k < 50; ++k) EXPECT_FALSE(check.observe(0.2, 0.2));  // refused once: the verdict stands
  EXPECT_TRUE(check.refused());
  // Small turns and non-finite ones say nothing; turns = 0 checks nothing.
  GyroCheck quiet{GyroCheckParams{}};
  for (int k = 0; k < 50; ++k) quiet.observe(0.01, -0.01), quiet.observe(NAN, 1.0), quiet.observe(0.2, INFINITY);
  EXPECT_FALSE(quiet.refused());
  GyroCheck off{GyroCheckParams{0, 0.087, 2.0}};
  for (int k = 0; k < 50; ++k) off.observe(0.2, -0.2);
  EXPECT_FALSE(off.refused());
}

}  // namespace
}  // namespace mrslam::slam
