// Wrong merges found on real data, each replayed: it must now be rejected (or, where the pair
// really overlaps, be correct).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "mrslam/bench/pair_maker.h"
#include "mrslam/bench/peer_frame_truth.h"
#include "mrslam/bench/scan_fixed_frame.h"
#include "mrslam/bench/trajectory_metrics.h"
#include "mrslam/fusion/map_fusion.h"
#include "mrslam/map_io.h"
#include "test_data.h"

using namespace mrslam;

namespace {

// Found by scripts/bench_merge's whole-map-vs-crop band (seed 2026): the west end of Freiburg
// 101's hall (a 700 x 700 crop) against the whole Freiburg 079 map in a random frame, accepted
// with V 0.985 and 0.989: Freiburg 079's corridor laid along the outside of Freiburg 101's hall
// wall, agreeing cell for cell, each map's free space behind the other's wall. Rejected now by
// the see-through check (see_through.h).
// (regressions/cross_building_accept, a whole map against a piece of ACES sharing one wall
// line and a T-junction, is still accepted: see the README's "What is left".)
TEST(MergeRegressions, ACorridorStubOfAnotherBuildingIsRejected) {
  const OccupancyGrid f101 = loadMap(test::referenceMap("freiburg-101"));
  const OccupancyGrid f079 = loadMap(test::referenceMap("freiburg-079"));
  struct Case { int col0, row0; Pose2D frame; };
  for (const Case& c : {Case{30, 27, {-25.1931, 36.815, 0.985402}}, Case{10, 8, {-9.89143, -23.4746, 4.20495}}}) {
    const int w = std::min(700, f101.width - c.col0), h = std::min(700, f101.height - c.row0);
    const OccupancyGrid crop = bench::trimUnknown(bench::cropGrid(f101, c.col0, c.row0, w, h));
    const fusion::FusionResult r = fusion::alignMaps(crop, bench::reframeGrid(f079, c.frame), fusion::FusionParams{});
    EXPECT_FALSE(r.accepted) << "crop at " << c.col0 << "," << c.row0 << ": V " << r.verdict.acceptance;
  }
}

// One robot's run of a log window, as the 8-robot benchmark's robots made it: trajectory and map.
struct WindowRun {
  OccupancyGrid map;
  bench::RobotTrack track;
};
WindowRun runWindow(const std::string& window, const std::vector<bench::LaserScan2D>& scans) {
  const std::string dir = ::testing::TempDir(), stem = dir + "/window_" + std::to_string(::getpid()) + "_" +
                                                       window.substr(0, window.find(':'));
  const auto run = test::runCommand(std::string(MRSLAM_SLAM_LOG_BIN) + " " +
                                    test::dataPath("logs/carmen_corrected/intel-corrected.log.gz") +
                                    " --simulated-imu --window " + window + " --trajectory " + stem + ".txt --map " +
                                    stem + ".yaml");
  EXPECT_EQ(run.status, 0) << run.output;
  WindowRun out;
  out.map = loadMap(stem + ".yaml");
  std::map<uint64_t, Pose2D> reference;
  for (const auto& s : scans) reference[static_cast<uint64_t>(std::llround(s.timestamp * 1e6)) * 1000] = s.pose;
  for (const auto& [stamp, pose] : bench::readTrajectory(stem + ".txt")) {
    const uint64_t key = static_cast<uint64_t>(std::llround(stamp * 1e6)) * 1000;
    out.track.estimate[key] = pose;
    if (reference.count(key)) out.track.reference[key] = reference[key];
  }
  return out;
}

// The 8-robot benchmark's one real wrong merge (README, "Still open"): robot8 (Intel 2222:2370 s)
// merging robot2 (336:480 s), a small overlap, accepted 1.05 degrees and 4.8 cells from the
// truth. Replayed offline as the benchmark's robots ran (simulated gyro): it must be rejected or
// correct. Correct is the benchmark's bar (1 degree, 2 cells) widened by the truth's own
// uncertainty: each robot's frame is placed in the world by a fit of its poses to the
// reference poses, whose residuals (about 3 cm each here) add to how far the truth can be off.
TEST(MergeRegressions, EightRobotPairRobot8FromRobot2IsRejectedOrCorrect) {
  const auto scans = bench::readCarmenScans(test::dataPath("logs/carmen_corrected/intel-corrected.log.gz"));
  const WindowRun robot8 = runWindow("2222:2370", scans), robot2 = runWindow("336:480", scans);
  double rms8 = 0, rms2 = 0;
  const auto frame8 = bench::frameInWorld(robot8.track, 20, &rms8), frame2 = bench::frameInWorld(robot2.track, 20, &rms2);
  ASSERT_TRUE(frame8 && frame2);
  const fusion::FusionResult r = fusion::alignMaps(robot8.map, robot2.map, fusion::FusionParams{});
  if (!r.accepted) SUCCEED() << "rejected: " << r.verdict.reason;
  else {
    const bench::FrameError e = bench::peerFrameError(r.pose, *frame8, *frame2, robot2.track);
    const double resolution = robot8.map.resolution;
    EXPECT_LE(e.yaw_deg, 1.0);
    EXPECT_LE(e.metres, 2 * resolution + rms8 + rms2) << "truth's own fit residuals " << rms8 << ", " << rms2 << " m";
  }
}

// The two truths of a merge between robots (peer_frame_truth.h: each robot's path fitted to the
// reference poses; scan_fixed_frame.h: the robots' scans aligned where both saw one place) on the
// multi-robot rostest's three Intel windows, replayed offline: each exists for every ordered
// pair, and they agree within the 2 cells / 0.5 degrees either can be trusted to (measured
// here: at most 1.1 cells and 0.3 degrees apart, the scan-fixed truths' own spread over their
// relations 0.05-1.4 cells); the merge lies within the rostest's bar of both.
TEST(MergeRegressions, TheScansAndTheReferencePosesAgreeOnWhereEachRobotsMapLies) {
  const std::string path = test::dataPath("logs/carmen_corrected/intel-corrected.log.gz");
  const auto scans = bench::readCarmenScans(path);
  const slam::RobotLog log = slam::readCarmenLog(path);
  const std::vector<std::string> windows = {"0:150", "336:480", "1864:2000"};
  std::vector<WindowRun> runs;
  for (const auto& w : windows) runs.push_back(runWindow(w, scans));
  bench::ScanFixedParams params;
  params.max_tried = 40;  // a second or two for the six pairs
  for (size_t n = 0; n < runs.size(); ++n)
    for (size_t m = 0; m < runs.size(); ++m) {
      if (n == m) continue;
      const std::string pair = windows[n] + " <- " + windows[m];
      const auto frame_n = bench::frameInWorld(runs[n].track), frame_m = bench::frameInWorld(runs[m].track);
      const auto scan_fixed = bench::scanFixedPeerFrame(log, runs[n].track, runs[m].track, params);
      ASSERT_TRUE(frame_n && frame_m && scan_fixed) << pair;
      EXPECT_GE(scan_fixed->relations, 5u) << pair;
      const bench::FrameError apart =
          bench::frameErrorAgainst(scan_fixed->truth, frame_n->inverse().compose(*frame_m), runs[m].track);
      const double cell = runs[n].map.resolution;
      EXPECT_LE(apart.metres, 2 * cell) << pair;
      EXPECT_LE(apart.yaw_deg, 0.5) << pair;
      const fusion::FusionResult r = fusion::alignMaps(runs[n].map, runs[m].map, fusion::FusionParams{});
      ASSERT_TRUE(r.accepted) << pair << ": " << r.verdict.reason;
      const bench::FrameError by_poses = bench::peerFrameError(r.pose, *frame_n, *frame_m, runs[m].track);
      const bench::FrameError by_scans = bench::frameErrorAgainst(r.pose, scan_fixed->truth, runs[m].track);
      std::printf("%s: merge %.2f cells / %.2f deg from the pose-fit truth, %.2f / %.2f from the scan-fixed truth "
                  "(%zu relations of %zu pairs, spread %.2f cells / %.2f deg); the truths %.2f cells / %.2f deg apart\n",
                  pair.c_str(), by_poses.metres / cell, by_poses.yaw_deg, by_scans.metres / cell, by_scans.yaw_deg,
                  scan_fixed->relations, scan_fixed->tried, scan_fixed->spread_m / cell, scan_fixed->spread_deg,
                  apart.metres / cell, apart.yaw_deg);
      EXPECT_LE(by_poses.metres, 2 * cell) << pair;
      EXPECT_LE(by_scans.metres, 2 * cell) << pair;
      EXPECT_LE(std::max(by_poses.yaw_deg, by_scans.yaw_deg), 1.0) << pair;
    }
}

}  // namespace

namespace {

// Pose error at B's grid centre (cells of B) and in heading (degrees), as the merge benchmark
// measures it.
std::pair<double, double> centreError(const OccupancyGrid& b, const Pose2D& estimate, const Pose2D& truth) {
  double cx, cy, ex, ey, tx, ty;
  b.origin.apply(b.width * b.resolution / 2, b.height * b.resolution / 2, cx, cy);
  estimate.apply(cx, cy, ex, ey);
  truth.apply(cx, cy, tx, ty);
  return {std::hypot(ex - tx, ey - ty) / b.resolution, std::abs(Pose2D::normalizeAngle(estimate.yaw - truth.yaw)) * 180 / M_PI};
}

std::string recordedMap(const std::string& pair, const std::string& which) {
  return std::string(MRSLAM_SOURCE_DIR) + "/test/data/multi_host_records/" + pair + "/" + which + ".yaml";
}

}  // namespace

// Two robots' live maps (scripts/multi_host's records, test/data/multi_host_records/README.md):
// Intel's two mirrored arcs overlay turned 180 degrees with V 0.973. A cleaner, smaller overlay
// at the right pose (V 0.997) beats that twin once conflicts count 3 times instead of 2: the
// twin must be rejected (or the answer right, within 1 degree and 3 cells: 2 plus the truth's
// own uncertainty).
TEST(MergeRegressions, MirroredArcsOfTwoRobotMapsAreNoMerge) {
  const OccupancyGrid a = loadMap(recordedMap("robot2_robot3_twin", "a"));
  const OccupancyGrid b = loadMap(recordedMap("robot2_robot3_twin", "b"));
  const fusion::FusionResult r = fusion::alignMaps(a, b, fusion::FusionParams{});
  if (r.accepted) {
    const auto [cells, deg] = centreError(b, r.pose, Pose2D{-2.1639, 2.2652, 3.08571});
    EXPECT_LE(deg, 1.0) << "accepted " << r.pose.x << " " << r.pose.y << " " << r.pose.yaw;
    EXPECT_LE(cells, 3.0);
  }
}

// An 8-robot run's final maps (scripts/bench_multi, README "Against the truth the scans fix"):
// robot8 held robot1 at a pose 1.23 degrees and 5.2 cells from the pose-fit truth, found from
// the one corridor stub the maps share (11 m of wall) while robot1's map reaches 15 m beyond
// it. Held or searched afresh, the pose must be rejected or right (1 degree, 2 cells).
TEST(MergeRegressions, AShortSharedStubDoesNotPlaceAMapThatReachesFarBeyondIt) {
  const OccupancyGrid a = loadMap(recordedMap("robot8_robot1_stub", "a"));
  const OccupancyGrid b = loadMap(recordedMap("robot8_robot1_stub", "b"));
  const Pose2D truth{-0.5429, 1.9971, 0.73867};
  for (const std::optional<Pose2D>& held : {std::optional<Pose2D>{}, std::optional<Pose2D>{Pose2D{-0.460, 2.130, 0.7172}}}) {
    const fusion::FusionResult r = fusion::alignMaps(a, b, fusion::FusionParams{}, held);
    if (!r.accepted) continue;
    const auto [cells, deg] = centreError(b, r.pose, truth);
    EXPECT_LE(deg, 1.0) << "accepted " << r.pose.x << " " << r.pose.y << " " << r.pose.yaw;
    EXPECT_LE(cells, 2.0);
  }
}

// The same run, robot1 holding robot3's right transform on the newest maps: an open-floor
// overlay 180 degrees away with 44 % of its walls on free space must not make it ambiguous.
TEST(MergeRegressions, AnOpenFloorOverlayDoesNotRevokeARightTransform) {
  const OccupancyGrid a = loadMap(recordedMap("robot1_robot3_held", "a"));
  const OccupancyGrid b = loadMap(recordedMap("robot1_robot3_held", "b"));
  const Pose2D held{3.4509660195442868, 1.7937145380066912, 1.0347680612524366};
  const fusion::FusionResult r = fusion::alignMaps(a, b, fusion::FusionParams{}, held);
  ASSERT_TRUE(r.accepted) << r.verdict.reason;
  const auto [cells, deg] = centreError(b, r.pose, Pose2D{3.4243, 1.7383, 1.03337});
  EXPECT_LE(deg, 1.0);
  EXPECT_LE(cells, 3.0);
}

// A relay of another 8-robot run (test/data/multi_host_records/README.md): robot1 placed robot8
// through robot2, accepted with 9.3 m of shared wall at 15 % of robot8's walls. As robot2 mapped
// on, the shared wall grew to 10.2 m and its share fell to 13 %, and three re-estimates revoked a
// transform 0.7 cells and 0.5 degrees from the truth. A held transform is not asked for that
// share again; one 3 m off is still refused on the same maps.
TEST(MergeRegressions, AHeldTransformIsNotRevokedForAShareThatFellAsTheMapsGrewApart) {
  const OccupancyGrid a = loadMap(recordedMap("robot2_robot8_relay_held", "a"));
  const OccupancyGrid b = loadMap(recordedMap("robot2_robot8_relay_held", "b"));
  const Pose2D held{-0.87424564655367953, 1.2283284938438577, 3.0246235242092623};
  const fusion::FusionResult r = fusion::alignMaps(a, b, fusion::FusionParams{}, held);
  ASSERT_TRUE(r.accepted) << r.verdict.reason;
  const auto [cells, deg] = centreError(b, r.pose, Pose2D{-0.9094, 1.2234, 3.03541});
  EXPECT_LE(deg, 1.0);
  EXPECT_LE(cells, 2.0);
  const fusion::FusionResult off = fusion::alignMaps(a, b, fusion::FusionParams{}, held.compose(Pose2D{3.0, 0.0, 0.0}));
  EXPECT_FALSE(off.accepted && centreError(b, off.pose, held).first > 10) << "a held pose 3 m off was confirmed";
}

// The mirrored arcs again, in a relay estimate of the same run (robot5 aligning robot3's map to
// robot2's): accepted at V 0.971, because the right pose, a clean overlay half the twin's size,
// was dropped on the way down the pyramid as "under half of the best" at w, though at 3w it
// beats the twin. Rejected, or the right heading (the merger's first estimate of this pair,
// V 0.996, -3.0278 rad; the twin is 180 degrees away).
TEST(MergeRegressions, TheRightPoseOfMirroredArcsIsNotDroppedBeforeTheAmbiguityCheck) {
  const OccupancyGrid a = loadMap(recordedMap("robot2_robot3_relay_twin", "a"));
  const OccupancyGrid b = loadMap(recordedMap("robot2_robot3_relay_twin", "b"));
  const fusion::FusionResult r = fusion::alignMaps(a, b, fusion::FusionParams{});
  if (r.accepted) {
    EXPECT_LE(std::abs(Pose2D::normalizeAngle(r.pose.yaw + 3.0278)) * 180 / M_PI, 1.0) << r.pose.yaw;
  }
}
