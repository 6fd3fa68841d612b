// The yardstick that checks relations against the scans (bench/scan_relations.h), on the real
// logs: it must find the motion the scans fix, refuse what they do not fix, and score a bent
// trajectory worse than a straight one; and the truth it gives for where one robot's map lies in
// another's (bench/scan_fixed_frame.h).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "mrslam/bench/scan_fixed_frame.h"
#include "mrslam/bench/scan_relations.h"
#include "test_logs.h"

namespace {

using mrslam::Pose2D;
namespace bench = mrslam::bench;

double metres(const Pose2D& a, const Pose2D& b) { return std::hypot(a.x - b.x, a.y - b.y); }
double degrees(const Pose2D& a, const Pose2D& b) { return std::abs(Pose2D::normalizeAngle(a.yaw - b.yaw)) * 180.0 / M_PI; }

TEST(ScanRelations, TwoRealScansAlignToOnePoseFromSeedsAroundIt) {
  const auto& log = mrslam::test::intelLog();
  for (size_t k : {100u, 400u, 700u}) {
    const Pose2D truth = log.records[k].reference.inverse().compose(log.records[k + 1].reference);
    double share = 0;
    const auto from_truth = bench::alignScans(log.records[k].scan, log.records[k + 1].scan, log.laser_in_base, truth, {}, &share);
    ASSERT_TRUE(from_truth) << "scans " << k << ", " << k + 1;
    EXPECT_GT(share, 0.6) << k;
    // The reference is good to a few centimetres and tenths of a degree here.
    EXPECT_LT(metres(*from_truth, truth), 0.05) << k;
    EXPECT_LT(degrees(*from_truth, truth), 1.0) << k;
    for (const Pose2D offset : {Pose2D{0.3, 0, 0.087}, Pose2D{-0.3, 0.1, -0.087}, Pose2D{0, -0.3, 0.05}}) {
      const auto from_off = bench::alignScans(log.records[k].scan, log.records[k + 1].scan, log.laser_in_base, truth.compose(offset));
      ASSERT_TRUE(from_off) << k;
      EXPECT_LT(metres(*from_off, *from_truth), 0.01) << k;
      EXPECT_LT(degrees(*from_off, *from_truth), 0.1) << k;
    }
  }
}

TEST(ScanRelations, ACorridorWithNothingAcrossItFixesNoRelation) {
  // Two parallel walls 2 m apart, seen the same from anywhere along them: the match can slide.
  mrslam::slam::LaserScan corridor;
  corridor.angle_min = -M_PI / 2, corridor.angle_increment = M_PI / 180, corridor.range_min = 0.01, corridor.range_max = 80;
  for (int b = 0; b < 180; ++b) {
    const double a = corridor.angle_min + b * corridor.angle_increment;
    corridor.ranges.push_back(static_cast<float>(std::min(1.0 / std::max(1e-3, std::abs(std::sin(a))), 15.0)));
  }
  EXPECT_FALSE(bench::alignScans(corridor, corridor, Pose2D{}, Pose2D{0.2, 0, 0}));
  bench::ScanRelationParams any_direction;
  any_direction.min_constraint = 0;
  EXPECT_TRUE(bench::alignScans(corridor, corridor, Pose2D{}, Pose2D{0.2, 0, 0}, any_direction));
}

TEST(ScanRelations, AMatchOnlyOneSidesClutterHoldsIsNotFoundFromTheOtherSide) {
  // Freiburg 079, scans 3234 and 3424 (another pass, 0.6 m apart): matched the one way, every
  // seed within 10 degrees ends 8 degrees from the reference, with 37 % of the points on walls;
  // matched the other way, at the reference's heading.
  const auto& log = mrslam::test::freiburg079Log();
  const size_t i = 3234, j = 3424;
  const Pose2D truth = log.records[i].reference.inverse().compose(log.records[j].reference);
  const auto forward = bench::alignScans(log.records[i].scan, log.records[j].scan, log.laser_in_base, truth);
  const auto reverse = bench::alignScans(log.records[j].scan, log.records[i].scan, log.laser_in_base, truth.inverse());
  ASSERT_TRUE(forward && reverse);
  EXPECT_GT(degrees(*forward, truth), 5.0);
  EXPECT_LT(degrees(reverse->inverse(), truth), 1.0);
  EXPECT_FALSE(bench::scanCheckedRelation(log, i, j)) << "the clutter's match became a relation";
}

TEST(ScanRelations, RelationsOnARealLogAreRightAndScoreABentTrajectoryWorse) {
  const auto& log = mrslam::test::intelLog();
  const auto checked = bench::scanCheckedRelations(log, 200, 2009);
  ASSERT_EQ(checked.relations.size(), 200u) << "of " << checked.tried << " tried";
  std::vector<Pose2D> reference;
  for (const auto& record : log.records) reference.push_back(record.reference);
  // No relation is a wrong match: each lies within what the reference's own errors allow.
  for (const auto& r : checked.relations) {
    const Pose2D motion = reference[r.i].inverse().compose(reference[r.j]);
    EXPECT_LT(metres(r.motion, motion), 0.15) << r.i << " -> " << r.j;
    EXPECT_LT(degrees(r.motion, motion), 2.0) << r.i << " -> " << r.j;
  }
  // The same trajectory bent by 1 degree at its middle scan.
  std::vector<Pose2D> bent = reference;
  const size_t middle = bent.size() / 2;
  const Pose2D pivot = reference[middle], turn{0, 0, M_PI / 180};
  for (size_t k = middle; k < bent.size(); ++k) bent[k] = pivot.compose(turn).compose(pivot.inverse().compose(reference[k]));
  const auto straight = bench::relationError(reference, checked.relations), crooked = bench::relationError(bent, checked.relations);
  // Measured: 0.028 m / 0.40 degrees straight, 0.092 m / 0.61 degrees bent (the relations across
  // the middle carry the whole bend).
  EXPECT_LT(straight.trans_mean, 0.05);
  EXPECT_GT(crooked.trans_mean, 2 * straight.trans_mean) << "the bend went unnoticed";
  EXPECT_GT(crooked.rot_mean, straight.rot_mean + 0.1 * M_PI / 180) << "the bend went unnoticed";
}

// Two robots on windows of the Intel log whose paths are the reference's, each in a map frame
// of its own: the truth the scans fix is where the frames really lie, to what the reference's
// own errors allow (a few centimetres), and a robot whose map is turned is found turned.
TEST(ScanFixedFrame, FindsWhereOneRobotsMapFrameLiesInAnothers) {
  const auto& log = mrslam::test::intelLog();
  const Pose2D frame_n{3.0, -2.0, 0.7}, frame_m{-5.0, 4.0, -2.1};
  const double t0 = log.records.front().scan.stamp;
  auto track = [&](double from, double to, const Pose2D& frame) {
    bench::RobotTrack t;
    for (const auto& record : log.records) {
      const double s = record.scan.stamp - t0;
      if (s < from || s >= to) continue;
      const auto key = static_cast<uint64_t>(std::llround(record.scan.stamp * 1e9));
      t.estimate[key] = frame.inverse().compose(record.reference);
      t.reference[key] = record.reference;
    }
    return t;
  };
  const bench::RobotTrack n = track(0, 150, frame_n), m = track(1864, 2000, frame_m);
  bench::ScanFixedParams params;
  params.max_tried = 30;  // of 77 candidate pairs: a second a run
  const auto found = bench::scanFixedPeerFrame(log, n, m, params);
  ASSERT_TRUE(found);
  EXPECT_GE(found->relations, 5u) << "of " << found->tried;
  const bench::FrameError error = bench::frameErrorAgainst(found->truth, frame_n.inverse().compose(frame_m), m);
  std::printf("%zu relations of %zu pairs; %.3f m, %.2f deg from the frames; spread %.3f m, %.2f deg\n", found->relations,
              found->tried, error.metres, error.yaw_deg, found->spread_m, found->spread_deg);
  // The frames are exact, the reference's poses between the two passes are not: its headings
  // disagree with what the scans fix by 0.50 degrees RMS on this log (README, "Against relations
  // the scans fix"). Measured: 1.5 cm and 0.24 degrees.
  EXPECT_LT(error.metres, 0.05);
  EXPECT_LT(error.yaw_deg, 0.5);
  EXPECT_LT(found->spread_m, 0.05);
  // M's map turned by 1 degree about its frame's origin: the truth turns with it.
  bench::RobotTrack turned = m;
  const Pose2D turn{0, 0, M_PI / 180};
  for (auto& [stamp, pose] : turned.estimate) pose = turn.compose(pose);
  const auto found_turned = bench::scanFixedPeerFrame(log, n, turned, params);
  ASSERT_TRUE(found_turned);
  const Pose2D expected = frame_n.inverse().compose(frame_m).compose(turn.inverse());
  EXPECT_LT(bench::frameErrorAgainst(found_turned->truth, expected, turned).metres, 0.03);
  EXPECT_LT(std::abs(Pose2D::normalizeAngle(found_turned->truth.yaw - found->truth.yaw) + M_PI / 180) * 180 / M_PI, 0.05);
}

}  // namespace
