// End-to-end map fusion on real data with known transforms, and the CLI's contract.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <opencv2/imgcodecs.hpp>

#include "mrslam/bench/pair_maker.h"
#include "mrslam/fusion/estimate_record.h"
#include "mrslam/fusion/fusion_params_io.h"
#include "mrslam/fusion/map_fusion.h"
#include "mrslam/fusion/peer_registry.h"
#include "mrslam/map_io.h"
#include "test_data.h"

namespace fs = std::filesystem;
using namespace mrslam;
using namespace mrslam::fusion;

namespace {

constexpr double kDeg = M_PI / 180.0;

// Error of an estimated pose of B's frame in A's frame against the truth: yaw error, and the
// displacement (in cells) of B's grid centre, which does not depend on where B's origin is.
struct PoseError {
  double yaw_deg, cells;
};
PoseError poseError(const OccupancyGrid& b, const Pose2D& estimate, const Pose2D& truth) {
  double cx, cy, ex, ey, tx, ty;
  b.origin.apply(b.width * b.resolution / 2, b.height * b.resolution / 2, cx, cy);
  estimate.apply(cx, cy, ex, ey);
  truth.apply(cx, cy, tx, ty);
  return {std::abs(std::remainder(estimate.yaw - truth.yaw, 2 * M_PI)) / kDeg,
          std::hypot(ex - tx, ey - ty) / b.resolution};
}

test::RunResult run(const std::string& args) {
  return test::runCommand(std::string(MRSLAM_MERGE_BIN) + " " + args);
}

// Inside the test process's own scratch folder (test_main.cpp), which is removed at the end.
fs::path tempDir() {
  fs::path dir = fs::path(::testing::TempDir()) / "map_fusion";
  fs::create_directories(dir);
  return dir;
}

// Maps of two time windows [first_a, end_a) and [first_b, end_b) of a real corrected CARMEN
// log, ray-cast along the reference poses with the benchmark's drift (seeded), B's map frame at
// `b_frame` in A's (the truth).
struct WindowPair {
  OccupancyGrid a, b;
};
WindowPair windowPair(const std::string& log, size_t first_a, size_t end_a, size_t first_b, size_t end_b,
                      const Pose2D& b_frame, unsigned drift_seed) {
  const auto scans = bench::readCarmenScans(test::dataPath("logs/carmen_corrected/" + log));
  EXPECT_GE(scans.size(), std::max(end_a, end_b));
  std::mt19937 rng(drift_seed);
  const bench::RaycastParams raycast;
  WindowPair pair;
  pair.a = bench::raycastMap(scans, first_a, end_a, Pose2D{}, raycast, rng);
  pair.b = bench::raycastMap(scans, first_b, end_b, b_frame, raycast, rng);
  return pair;
}

void expectCorrect(const FusionResult& r, const OccupancyGrid& b, const Pose2D& truth) {
  ASSERT_TRUE(r.accepted) << r.verdict.reason;
  const PoseError e = poseError(b, r.pose, truth);
  EXPECT_LE(e.yaw_deg, 1.0);
  EXPECT_LE(e.cells, 2.0);
}
}  // namespace

TEST(MapFusion, AlignsTwoRealCropsUnderALargeRotation) {
  const OccupancyGrid intel = loadMap(test::referenceMap("intel"));
  const OccupancyGrid a = bench::cropGrid(intel, 0, 0, 520, 761);
  const Pose2D truth{25.0, -18.0, 123.0 * kDeg};
  const OccupancyGrid b = bench::reframeGrid(bench::cropGrid(intel, 300, 100, 514, 661), truth);
  const FusionResult r = alignMaps(a, b, FusionParams{});
  ASSERT_TRUE(r.accepted) << r.verdict.reason;
  const PoseError e = poseError(b, r.pose, truth);
  EXPECT_LE(e.yaw_deg, 1.0);
  EXPECT_LE(e.cells, 2.0);
  EXPECT_GT(r.verdict.acceptance, 0.9);
}

TEST(MapFusion, AlignsMapsOfTwoTimeWindowsOfARealLog) {
  // Two "robots": scans 0-449 and 350-909 of the Intel log (910 scans), the second in its own frame.
  const Pose2D truth{-12.0, 31.0, -71.0 * kDeg};
  const WindowPair maps = windowPair("intel-corrected.log.gz", 0, 450, 350, 910, truth, 1);
  expectCorrect(alignMaps(maps.a, maps.b, FusionParams{}), maps.b, truth);
}

// Runs every estimate the registry asks for, direct ones first, as the merge nodelet's worker does.
static void settle(PeerRegistry& registry, const OccupancyGrid& own, const FusionParams& params, double clock) {
  const MapSummary summary = summarize(own);
  for (int step = 0; step < 100; ++step) {
    if (const auto next = registry.nextToEstimate(summary, clock)) {
      registry.applyEstimate(*next, alignMaps(own, *registry.peers().at(*next).map, params), summary, clock);
    } else if (const auto relay = registry.nextRelayToEstimate(clock)) {
      const auto& [id, via] = *relay;
      registry.applyRelayEstimate(id, via, alignMaps(*registry.peers().at(via).map, *registry.peers().at(id).map, params),
                                  clock);
    } else {
      return;
    }
  }
  ADD_FAILURE() << "the registry kept asking for estimates on unchanged maps";
}

TEST(PeerRelay, AMapThatDoesNotOverlapOursIsPlacedWhereTwoPeersThatOverlapBothAgree) {
  // Four robots' maps of the real Intel map: ours (A) in the west, C in the east, B and D (each
  // in a frame of its own) overlapping both. C shares nothing with A, so it cannot be accepted
  // directly; aligned to B's and D's maps, the two chains agree and place it where it belongs.
  const OccupancyGrid intel = loadMap(test::referenceMap("intel"));
  const OccupancyGrid a = bench::cropGrid(intel, 0, 0, 400, 761);
  const Pose2D b_truth{4.0, -7.0, 38.0 * kDeg}, c_truth{-9.0, 15.0, -104.0 * kDeg}, d_truth{20.0, 3.0, 171.0 * kDeg};
  auto piece = [&](int col0, int row0, int cols, int rows, const Pose2D& frame) {
    return std::make_shared<const OccupancyGrid>(bench::reframeGrid(bench::cropGrid(intel, col0, row0, cols, rows), frame));
  };
  const auto b = piece(250, 0, 400, 761, b_truth), c = piece(500, 0, 314, 761, c_truth);
  const auto d = piece(220, 0, 480, 480, d_truth);
  const FusionParams params;
  PeerRegistry registry("robotA");
  registry.updatePeer("robotB", b, 1, 0.0);
  registry.updatePeer("robotC", c, 1, 0.0);
  settle(registry, a, params, 1.0);
  ASSERT_TRUE(registry.peers().at("robotB").accepted) << registry.peers().at("robotB").last_attempt.reason;
  ASSERT_FALSE(registry.peers().at("robotC").accepted) << "no overlap with our map: nothing to accept directly";
  ASSERT_TRUE(registry.peers().at("robotC").relays.at("robotB").accepted) << "C's map fits B's";
  EXPECT_FALSE(registry.placementOf(registry.peers().at("robotC"))) << "one chain is not enough by default";

  registry.updatePeer("robotD", d, 1, 2.0);
  settle(registry, a, params, 2.0);
  ASSERT_TRUE(registry.peers().at("robotD").accepted) << registry.peers().at("robotD").last_attempt.reason;
  const auto placed = registry.placementOf(registry.peers().at("robotC"));
  ASSERT_TRUE(placed) << registry.peers().at("robotC").relays.at("robotD").last_attempt.reason;
  EXPECT_EQ(placed->vias, (std::vector<std::string>{"robotB", "robotD"}));
  const PoseError e = poseError(*c, placed->pose, c_truth);
  EXPECT_LE(e.yaw_deg, 1.0);
  EXPECT_LE(e.cells, 2.0);
  EXPECT_TRUE(registry.estimateIsCurrent(registry.peers().at("robotC"), summarize(a)));
  EXPECT_FALSE(registry.nextRelayToEstimate(3.0)) << "nothing changed";
}

// A fusion result as the registry sees it, for the bookkeeping tests.
static FusionResult relayResult(bool accepted, Pose2D pose) {
  FusionResult r;
  r.accepted = r.verdict.accepted = accepted;
  r.pose = pose;
  r.verdict.acceptance = 0.98;
  r.verdict.reason = accepted ? "" : "test rejection";
  return r;
}

TEST(PeerRelay, ARelayLastsOnlyAsLongAsTheTransformItGoesThrough) {
  const auto map = std::make_shared<const OccupancyGrid>(loadMap(test::referenceMap("intel")));
  const MapSummary own = summarize(*map);
  PeerRegistryParams params;
  params.relay_min_vias = 1;  // one chain places a peer: the bookkeeping of a single relay
  PeerRegistry registry("robot1", params);
  for (const char* id : {"robot2", "robot3", "robot4"}) registry.updatePeer(id, map, 1, 0.0);
  registry.applyEstimate("robot2", relayResult(true, {1, 0, M_PI / 2}), own, 1.0);
  registry.applyEstimate("robot3", relayResult(false, {}), own, 1.0);
  registry.applyEstimate("robot4", relayResult(true, {0, 5, 0}), own, 1.0);
  // Never tried first, through the accepted peers in id order; none through an unaccepted one.
  EXPECT_EQ(registry.nextRelayToEstimate(2.0), std::make_pair(std::string("robot3"), std::string("robot2")));
  EXPECT_TRUE(registry.applyRelayEstimate("robot3", "robot2", relayResult(true, {2, 0, 0}), 2.0));
  const auto placed = registry.placementOf(registry.peers().at("robot3"));
  ASSERT_TRUE(placed);
  EXPECT_NEAR(placed->pose.x, 1.0, 1e-9);  // robot2's frame turned 90 degrees: (2, 0) lands at (1, 2)
  EXPECT_NEAR(placed->pose.y, 2.0, 1e-9);
  EXPECT_NEAR(placed->pose.yaw, M_PI / 2, 1e-9);
  EXPECT_EQ(registry.placementOf(registry.peers().at("robot3"))->vias, std::vector<std::string>{"robot2"});
  EXPECT_FALSE(registry.parentOf()) << "the tf tree holds direct accepts only";

  // robot2's transform revoked: robot3 is no longer placed, and both are tried through robot4.
  for (int i = 0; i < params.revoke_after_rejections; ++i) registry.applyEstimate("robot2", relayResult(false, {}), own, 4.0);
  ASSERT_FALSE(registry.peers().at("robot2").accepted);
  EXPECT_FALSE(registry.placementOf(registry.peers().at("robot3")));
  EXPECT_EQ(registry.nextRelayToEstimate(5.0), std::make_pair(std::string("robot2"), std::string("robot4")));
  registry.applyRelayEstimate("robot2", "robot4", relayResult(false, {}), 5.0);
  EXPECT_EQ(registry.nextRelayToEstimate(5.0), std::make_pair(std::string("robot3"), std::string("robot4")));

  // A direct accept wins over any relay; a restart of the via forgets the relays through it.
  registry.applyEstimate("robot2", relayResult(true, {1, 0, M_PI / 2}), own, 6.0);
  ASSERT_TRUE(registry.placementOf(registry.peers().at("robot3")));
  registry.applyEstimate("robot3", relayResult(true, {7, 7, 0}), own, 7.0);
  EXPECT_TRUE(registry.placementOf(registry.peers().at("robot3"))->vias.empty());
  EXPECT_NEAR(registry.placementOf(registry.peers().at("robot3"))->pose.x, 7.0, 1e-9);
  registry.updatePeer("robot2", map, 0, 8.0);  // restarted: a new map frame
  EXPECT_TRUE(registry.peers().at("robot3").relays.empty());

  // Switched off, nothing is relayed.
  params.relay_min_vias = 0;
  PeerRegistry off("robot1", params);
  for (const char* id : {"robot2", "robot3"}) off.updatePeer(id, map, 1, 0.0);
  off.applyEstimate("robot2", relayResult(true, {}), own, 1.0);
  off.applyEstimate("robot3", relayResult(false, {}), own, 1.0);
  EXPECT_FALSE(off.nextRelayToEstimate(2.0));
}

TEST(PeerRelay, APeerIsRelayedThroughAtMostEightViasHoweverManyWeAccept) {
  // Each relay is a fusion: with a large team, the work per peer stays bounded.
  const auto map = std::make_shared<const OccupancyGrid>(loadMap(test::referenceMap("intel")));
  const MapSummary own = summarize(*map);
  PeerRegistry registry("robot00");
  for (int k = 1; k <= 10; ++k) {
    const std::string id = "robot" + std::string(k < 10 ? "0" : "") + std::to_string(k);
    registry.updatePeer(id, map, 1, 0.0);
    registry.applyEstimate(id, relayResult(true, {}), own, 1.0);
  }
  registry.updatePeer("robot11", map, 1, 0.0);
  registry.applyEstimate("robot11", relayResult(false, {}), own, 1.0);
  std::vector<std::string> vias;
  while (const auto next = registry.nextRelayToEstimate(2.0)) {
    ASSERT_EQ(next->first, "robot11");
    vias.push_back(next->second);
    registry.applyRelayEstimate(next->first, next->second, relayResult(false, {}), 2.0);
    ASSERT_LE(vias.size(), 10u);
  }
  EXPECT_EQ(vias.size(), 8u);
  EXPECT_EQ(vias.back(), "robot08");
}

TEST(PeerRelay, ChainsThatDisagreeDoNotPlaceAPeerAndTheAgreeingOnesArePlacedAtTheirMean) {
  const auto map = std::make_shared<const OccupancyGrid>(loadMap(test::referenceMap("intel")));
  const MapSummary own = summarize(*map);
  PeerRegistry registry("robot1");  // the defaults: two chains within 0.15 m and 1 degree
  for (const char* id : {"robot2", "robot3", "robot4", "robot5"}) registry.updatePeer(id, map, 1, 0.0);
  for (const char* id : {"robot2", "robot3", "robot4"}) registry.applyEstimate(id, relayResult(true, {}), own, 1.0);
  registry.applyEstimate("robot5", relayResult(false, {}), own, 1.0);
  // Through robot2 and robot3: 0.4 m apart at the map's centre, so neither places robot5.
  registry.applyRelayEstimate("robot5", "robot2", relayResult(true, {10.0, 0, 0}), 2.0);
  registry.applyRelayEstimate("robot5", "robot3", relayResult(true, {10.4, 0, 0}), 2.0);
  EXPECT_FALSE(registry.placementOf(registry.peers().at("robot5")));
  // robot4's chain agrees with robot3's (0.1 m): placed at their mean, robot2's left out.
  registry.applyRelayEstimate("robot5", "robot4", relayResult(true, {10.5, 0, 0}), 2.0);
  const auto placed = registry.placementOf(registry.peers().at("robot5"));
  ASSERT_TRUE(placed);
  EXPECT_EQ(placed->vias, (std::vector<std::string>{"robot3", "robot4"}));
  EXPECT_NEAR(placed->pose.x, 10.45, 1e-9);

  // Headings: with any distance allowed, 0.8 degrees apart agree and 2 degrees do not.
  PeerRegistryParams heading_only;
  heading_only.relay_agree_m = 1e3;
  PeerRegistry headings("robot1", heading_only);
  for (const char* id : {"robot2", "robot3", "robot5"}) headings.updatePeer(id, map, 1, 0.0);
  for (const char* id : {"robot2", "robot3"}) headings.applyEstimate(id, relayResult(true, {}), own, 1.0);
  headings.applyRelayEstimate("robot5", "robot2", relayResult(true, {10, 0, 0}), 2.0);
  headings.applyRelayEstimate("robot5", "robot3", relayResult(true, {10, 0, 0.8 * kDeg}), 2.0);
  ASSERT_TRUE(headings.placementOf(headings.peers().at("robot5")));
  EXPECT_NEAR(headings.placementOf(headings.peers().at("robot5"))->pose.yaw, 0.4 * kDeg, 1e-9);
  headings.applyRelayEstimate("robot5", "robot3", relayResult(true, {10, 0, 2.0 * kDeg}), 3.0);
  EXPECT_FALSE(headings.placementOf(headings.peers().at("robot5")));
}

TEST(MapFusion, AHeldPoseIsConfirmedOnlyWhereTheMapsStillSupportIt) {
  // The Intel windows above, with a search that proposes nothing (no rotation candidates, no
  // segments, no finer retry): only the held pose, the merger's current transform, can be the
  // answer. Near the truth (1.5 cells and half a degree off, as after the maps grew) it is
  // tracked back and verified like any final; 3 m off it explains nothing and is rejected.
  const Pose2D truth{-12.0, 31.0, -71.0 * kDeg};
  const WindowPair maps = windowPair("intel-corrected.log.gz", 0, 450, 350, 910, truth, 1);
  FusionParams blind;
  blind.rotation_candidates = 0;
  blind.use_segments = false;
  blind.retry_finer = 0;
  EXPECT_FALSE(alignMaps(maps.a, maps.b, blind).accepted);
  const Pose2D near = truth.compose(Pose2D{0.05, -0.05, 0.5 * kDeg});
  const FusionResult confirmed = alignMaps(maps.a, maps.b, blind, near);
  expectCorrect(confirmed, maps.b, truth);
  const FusionResult wrong = alignMaps(maps.a, maps.b, blind, truth.compose(Pose2D{3.0, 0.0, 0.0}));
  EXPECT_FALSE(wrong.accepted) << "a held pose 3 m off was confirmed";
}

TEST(EstimateRecord, AMergersRecordReplaysOfflineToTheSameEstimate) {
  // What a merger with record_dir writes: the Intel windows above estimated with a held pose
  // (accepted), then B against another building (rejected). mrslam_merge on the recorded files,
  // given the recorded held pose, must reach the merger's answer for both.
  const fs::path dir = tempDir() / "records";
  fs::remove_all(dir);
  const Pose2D truth{-12.0, 31.0, -71.0 * kDeg};
  const WindowPair maps = windowPair("intel-corrected.log.gz", 0, 450, 350, 910, truth, 1);
  const Pose2D held = truth.compose(Pose2D{0.05, -0.05, 0.5 * kDeg});
  const FusionResult accepted = alignMaps(maps.a, maps.b, FusionParams{}, held);
  ASSERT_TRUE(accepted.accepted) << accepted.verdict.reason;
  recordEstimate(dir.string(), "robot2", "", maps.a, maps.b, held, accepted, 100.0);
  const OccupancyGrid other = loadMap(test::referenceMap("freiburg-079"));
  const FusionResult rejected = alignMaps(other, maps.b, FusionParams{});
  ASSERT_FALSE(rejected.accepted);
  recordEstimate(dir.string(), "robot2", "", other, maps.b, std::nullopt, rejected, 101.0);

  std::ifstream table(dir / "robot2" / "estimates.tsv");
  std::vector<std::string> lines;
  for (std::string line; std::getline(table, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0] + "\n", kEstimateRecordHeader);
  EXPECT_EQ(lines[1].rfind("100.000\t1\t", 0), 0u) << lines[1];
  EXPECT_EQ(lines[2].rfind("101.000\t0\t", 0), 0u) << lines[2];
  EXPECT_NE(lines[2].find(rejected.verdict.reason), std::string::npos) << lines[2];

  // The held pose as the table holds it (column 8), back through the command line.
  std::vector<std::string> columns;
  for (size_t from = 0, tab; from <= lines[1].size(); from = tab + 1) {
    tab = lines[1].find('\t', from);
    if (tab == std::string::npos) tab = lines[1].size();
    columns.push_back(lines[1].substr(from, tab - from));
  }
  ASSERT_EQ(columns.size(), 9u);
  const std::string record = (dir / "robot2").string();
  const test::RunResult replay_accepted =
      run("--json --held " + columns[7] + " " + record + "/accepted_a.yaml " + record + "/accepted_b.yaml");
  ASSERT_EQ(replay_accepted.status, 0) << replay_accepted.output;
  EXPECT_NE(replay_accepted.output.find("\"accepted\": true"), std::string::npos) << replay_accepted.output;
  double x = 0, y = 0, yaw = 0;
  ASSERT_EQ(std::sscanf(replay_accepted.output.c_str() + replay_accepted.output.find("\"x\""),
                        "\"x\": %lf, \"y\": %lf, \"yaw\": %lf", &x, &y, &yaw), 3);
  EXPECT_NEAR(x, accepted.pose.x, 1e-6);
  EXPECT_NEAR(y, accepted.pose.y, 1e-6);
  EXPECT_NEAR(yaw, accepted.pose.yaw, 1e-6);
  const test::RunResult replay_rejected = run("--json " + record + "/latest_a.yaml " + record + "/latest_b.yaml");
  ASSERT_EQ(replay_rejected.status, 0) << replay_rejected.output;
  EXPECT_NE(replay_rejected.output.find("\"accepted\": false"), std::string::npos) << replay_rejected.output;
  EXPECT_NE(replay_rejected.output.find(rejected.verdict.reason), std::string::npos) << replay_rejected.output;

  EXPECT_THROW(recordEstimate(dir.string(), "../robot2", "", maps.a, maps.b, held, accepted, 102.0), std::invalid_argument);
  EXPECT_THROW(recordEstimate(dir.string(), "robot2", "..", maps.a, maps.b, held, accepted, 102.0), std::invalid_argument);
  // A relay's record lies in a subfolder of the peer's: a peer whose id holds "_via_" cannot
  // write over it (ids robot2 via robot3 and "robot2_via_robot3" used to share one folder).
  recordEstimate(dir.string(), "robot2", "robot3", other, maps.b, std::nullopt, rejected, 103.0);
  recordEstimate(dir.string(), "robot2_via_robot3", "", maps.a, maps.b, held, accepted, 104.0);
  for (const fs::path& table : {dir / "robot2" / "via_robot3" / "estimates.tsv", dir / "robot2_via_robot3" / "estimates.tsv"}) {
    std::ifstream in(table);
    size_t count = 0;
    for (std::string line; std::getline(in, line);) ++count;
    EXPECT_EQ(count, 2u) << table << ": the header and its own estimate";
  }
  EXPECT_EQ(loadMap((dir / "robot2" / "via_robot3" / "latest_a.yaml").string()).width, other.width);
  EXPECT_NE(run("--held 1,2 " + record + "/latest_a.yaml " + record + "/latest_b.yaml").status, 0);
  fs::remove_all(dir);
}

TEST(MapFusion, FindsCorridorsTheCoarseLevelBlursWithoutAFinerSearch) {
  // Two windows of the real Freiburg 079 log (long corridors, B turned by 90 degrees), with
  // the benchmark's drift. With the rotation spectra taken on the level they once were
  // (spectrum_max_cells 400) the rotation candidate is 2 degrees off, so on the coarse level
  // the corridors lie a coarse cell apart. Scored there with the full disagreement weight,
  // those cells count as conflicts, the true pose never survives to the finer levels and the
  // best pose shares too little wall; the lower coarse weight keeps it (a finer second search,
  // retry_finer, used to be what found it, at four times the cost).
  const Pose2D truth{-9.51427, -9.20342, 1.56724};
  const WindowPair maps = windowPair("freiburg-079-corrected.log.gz", 1149, 2704, 2140, 3703, truth, 2);
  FusionParams full_weight;
  full_weight.spectrum_max_cells = 400;
  full_weight.rotation_candidates = 3;
  full_weight.coarse_disagreement_weight = full_weight.disagreement_weight;
  const FusionResult blurred = alignMaps(maps.a, maps.b, full_weight);
  EXPECT_FALSE(blurred.accepted);
  EXPECT_TRUE(blurred.verdict.no_overlap_found) << blurred.verdict.reason;
  FusionParams coarse_weight = full_weight;
  coarse_weight.coarse_disagreement_weight = FusionParams{}.coarse_disagreement_weight;
  expectCorrect(alignMaps(maps.a, maps.b, coarse_weight), maps.b, truth);
  FusionParams finer = full_weight;
  finer.retry_finer = 1;
  expectCorrect(alignMaps(maps.a, maps.b, finer), maps.b, truth);
  expectCorrect(alignMaps(maps.a, maps.b, FusionParams{}), maps.b, truth);
}

TEST(MapFusion, TakesRotationSpectraFineEnoughToSeeASecondDirection) {
  // Two windows of the real Freiburg 079 log (a 50-75 % pair of the merge benchmark, seed 99).
  // A is one long corridor, 885 x 308 cells. Its Radon spectrum taken on 222 x 77 cells
  // (spectrum_max_cells 400) correlates with B's in a single broad peak 15-17 degrees off the
  // truth: no other rotation was ever searched, and the pose shared 1 m of wall. On the next
  // finer level the spectra show the side corridors' direction too (every drift seed tried).
  const Pose2D truth{-22.6048, -2.48698, 1.68233};
  const WindowPair maps = windowPair("freiburg-079-corrected.log.gz", 2355, 3557, 951, 2598, truth, 1);
  FusionParams coarse_spectrum;
  coarse_spectrum.spectrum_max_cells = 400;
  const FusionResult blind = alignMaps(maps.a, maps.b, coarse_spectrum);
  EXPECT_FALSE(blind.accepted);
  EXPECT_TRUE(blind.verdict.no_overlap_found) << blind.verdict.reason;
  expectCorrect(alignMaps(maps.a, maps.b, FusionParams{}), maps.b, truth);
}

TEST(MapFusion, AcceptsRealWindowsWhoseWallsAgreeLess) {
  // Two windows of the real ACES log (a pair of the merge benchmark, seed 42). ACES walls are
  // cluttered, so even at the true pose only ~70 % of B's obstacles (in A's known space) land on
  // A's: this pair was rejected while the wall agreement floor was 0.75.
  const Pose2D truth{-34.34201, 27.19592, 0.762330};
  const WindowPair maps = windowPair("aces-corrected.log.gz", 193, 424, 30, 172, truth, 3);
  const FusionResult r = alignMaps(maps.a, maps.b, FusionParams{});
  EXPECT_LT(r.verdict.wall_agreement, 0.75);
  expectCorrect(r, maps.b, truth);
}

TEST(MapFusion, SetsAsideATwinThatContradictsTheMaps) {
  // Two crops of the real ACES map (a pair of the merge benchmark, seed 7). ACES is nearly
  // symmetric under a half turn: its twin pose overlays more of the maps than the truth and
  // outscores it, but 3.6 % of that overlap disagrees (V 0.964 < 0.97), so it is no rival to
  // the truth (V 1.0). Before the twin was set aside, the merge was rejected for its V.
  const OccupancyGrid aces = loadMap(test::referenceMap("aces"));
  const OccupancyGrid a = bench::trimUnknown(bench::cropGrid(aces, 103, 55, 575, 577));
  const Pose2D truth{25.5555, 7.93858, 0.700291};
  const OccupancyGrid b = bench::reframeGrid(bench::trimUnknown(bench::cropGrid(aces, 220, 379, 701, 758)), truth);
  const FusionResult r = alignMaps(a, b, FusionParams{});
  EXPECT_GE(r.set_aside, 1);
  expectCorrect(r, b, truth);
}

TEST(MapFusion, ResamplesAMapOfCoarserResolution) {
  const OccupancyGrid aces = loadMap(test::referenceMap("aces"));
  const OccupancyGrid a = bench::cropGrid(aces, 0, 0, 800, 1178);
  const Pose2D truth{-5.0, 7.5, 200.0 * kDeg};
  OccupancyGrid b = bench::reframeGrid(bench::cropGrid(aces, 300, 0, 878, 1178), truth);
  // Halve B's resolution (occupied wins), as a robot mapping at 0.10 m would deliver.
  OccupancyGrid coarse;
  coarse.resolution = 0.10, coarse.origin = b.origin, coarse.width = b.width / 2, coarse.height = b.height / 2;
  coarse.data.assign(static_cast<size_t>(coarse.width) * coarse.height, -1);
  for (int r = 0; r < coarse.height; ++r)
    for (int c = 0; c < coarse.width; ++c)
      for (int k = 0; k < 4; ++k) {
        const int v = b.at(2 * c + k % 2, 2 * r + k / 2);
        int8_t& out = coarse.at(c, r);
        if (v >= 65 || (v >= 0 && out < 0)) out = static_cast<int8_t>(v);
      }
  const FusionResult r = alignMaps(a, coarse, FusionParams{});
  ASSERT_TRUE(r.accepted) << r.verdict.reason;
  const PoseError e = poseError(coarse, r.pose, truth);
  EXPECT_LE(e.yaw_deg, 1.0);
  EXPECT_LE(e.cells, 2.0);  // in 0.10 m cells of B
}

TEST(MapFusion, RejectsMapsOfDifferentBuildings) {
  const OccupancyGrid intel = loadMap(test::referenceMap("intel"));
  for (const char* other : {"aces", "freiburg-079", "freiburg-101"}) {
    const FusionResult r = alignMaps(intel, loadMap(test::referenceMap(other)), FusionParams{});
    EXPECT_FALSE(r.accepted) << other;
    EXPECT_FALSE(r.verdict.reason.empty());
  }
}

TEST(MapFusion, IsReproducible) {
  const OccupancyGrid a = loadMap(test::robotMap("avz5floor_closed"));
  const OccupancyGrid b = loadMap(test::robotMap("avz5floor_open"));
  const FusionResult r1 = alignMaps(a, b, FusionParams{}), r2 = alignMaps(a, b, FusionParams{});
  EXPECT_EQ(r1.accepted, r2.accepted);
  EXPECT_DOUBLE_EQ(r1.pose.x, r2.pose.x);
  EXPECT_DOUBLE_EQ(r1.pose.yaw, r2.pose.yaw);
}

TEST(MergeCli, JsonOutputAndMergedMapForARealPair) {
  const fs::path dir = tempDir();
  const OccupancyGrid intel = loadMap(test::referenceMap("intel"));
  const Pose2D truth{-30.0, 12.0, 250.0 * kDeg};
  saveMap(bench::cropGrid(intel, 0, 0, 500, 761), (dir / "a.yaml").string());
  saveMap(bench::reframeGrid(bench::cropGrid(intel, 314, 0, 500, 761), truth), (dir / "b.yaml").string());
  const test::RunResult r = run("--json -o " + (dir / "merged.yaml").string() + " " + (dir / "a.yaml").string() +
                          " " + (dir / "b.yaml").string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("\"accepted\": true"), std::string::npos) << r.output;
  double x = 0, y = 0, yaw = 0;
  ASSERT_EQ(std::sscanf(r.output.c_str() + r.output.find("\"x\""), "\"x\": %lf, \"y\": %lf, \"yaw\": %lf", &x, &y, &yaw), 3);
  const OccupancyGrid b = loadMap((dir / "b.yaml").string());
  const PoseError e = poseError(b, Pose2D{x, y, yaw}, truth);
  EXPECT_LE(e.yaw_deg, 1.0);
  EXPECT_LE(e.cells, 2.0);
  const OccupancyGrid merged = loadMap((dir / "merged.yaml").string());
  EXPECT_GE(merged.width, 780);  // covers both halves of the lab
  EXPECT_GE(merged.height, 740);
}

TEST(MergeCli, RejectedMergeIsNotAnError) {
  const test::RunResult r = run("--json " + test::referenceMap("intel") + " " + test::referenceMap("freiburg-079"));
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("\"accepted\": false"), std::string::npos) << r.output;
  // Every check's figure is printed, so a user sees which one failed and by how much.
  for (const char* key : {"wall_agreement", "shared_wall_m", "shared_wall_fraction", "entropy_increase",
                          "distinctiveness", "ambiguity", "seen_through", "lever", "reason"})
    EXPECT_NE(r.output.find("\"" + std::string(key) + "\": "), std::string::npos) << key << ": " << r.output;
}

TEST(MergeCli, BadInputGivesOneLineNamingTheFileAndExitTwo) {
  const fs::path dir = tempDir();
  const std::string good = test::referenceMap("intel");
  const std::string tail = "origin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  cv::imwrite((dir / "unknown.pgm").string(), cv::Mat(50, 50, CV_8U, cv::Scalar(205)));
  cv::imwrite((dir / "free.pgm").string(), cv::Mat(50, 50, CV_8U, cv::Scalar(254)));
  std::ofstream(dir / "all_unknown.yaml") << "image: unknown.pgm\nresolution: 0.05\n" << tail;
  std::ofstream(dir / "no_edges.yaml") << "image: free.pgm\nresolution: 0.05\n" << tail;
  std::ofstream(dir / "nan.yaml") << "image: free.pgm\nresolution: nan\n" << tail;
  std::ofstream(dir / "negative.yaml") << "image: free.pgm\nresolution: -0.05\n" << tail;
  std::ofstream(dir / "broken.yaml") << "image: free.pgm\n  resolution: [\n";
  std::ofstream(dir / "short.pgm") << "P5\n400 400\n255\nabc";
  std::ofstream(dir / "size_mismatch.yaml") << "image: short.pgm\nresolution: 0.05\n" << tail;
  std::ofstream(dir / "bad.yaml") << "nonsense_key: 1\n";
  // Inputs that once crashed, overflowed or printed more than one line (issue 15).
  std::ofstream(dir / "p2.pgm") << "P2\n100000 100000\n255\n0 0 0\n";
  std::ofstream(dir / "huge_p2.yaml") << "image: p2.pgm\nresolution: 0.05\n" << tail;
  std::ofstream(dir / "overflow.pgm") << "P5\n4294967296 4294967296\n255\n";
  std::ofstream(dir / "overflow.yaml") << "image: overflow.pgm\nresolution: 0.05\n" << tail;
  {
    std::ifstream png(test::robotMap("rail_lab").substr(0, test::robotMap("rail_lab").size() - 5) + ".png", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(png)), std::istreambuf_iterator<char>());
    bytes[60] = static_cast<char>(bytes[60] ^ 0x55);  // inside the image data: its CRC no longer holds
    std::ofstream(dir / "bad_crc.png", std::ios::binary) << bytes;
  }
  std::ofstream(dir / "bad_crc.yaml") << "image: bad_crc.png\nresolution: 0.05\n" << tail;
  std::ofstream(dir / "far.yaml") << "image: free.pgm\nresolution: 0.05\norigin: [1e300, 0, 0]\n";
  fs::create_directories(dir / "a_directory.yaml");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {(dir / "missing.yaml").string(), "no such file"},
      {(dir / "broken.yaml").string(), "malformed yaml"},
      {(dir / "nan.yaml").string(), "resolution"},
      {(dir / "negative.yaml").string(), "resolution"},
      {(dir / "all_unknown.yaml").string(), "all unknown"},
      {(dir / "no_edges.yaml").string(), "no obstacle edges"},
      {(dir / "size_mismatch.yaml").string(), "short.pgm"},
      {(dir / "huge_p2.yaml").string(), "100000 x 100000"},
      {(dir / "overflow.yaml").string(), "overflow.pgm"},
      {(dir / "bad_crc.yaml").string(), "bad CRC"},
      {(dir / "far.yaml").string(), "from the frame"},
      {(dir / "a_directory.yaml").string(), "not a file"},
  };
  for (const auto& [file, problem] : cases) {
    const test::RunResult r = run(good + " " + file);
    EXPECT_EQ(r.status, 2) << file << ": " << r.output;
    EXPECT_NE(r.output.find(problem), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(fs::path(file).filename().string()), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
  for (const auto& [file, problem] : cases) {  // no absurd numbers either (an origin of 1e300 once printed 300 digits)
    const test::RunResult r = run(good + " " + file);
    EXPECT_LT(r.output.size(), 300u) << r.output;
  }
  // A write that fails (a full disk) is an error, not exit 0.
  fs::create_symlink("/dev/full", dir / "full.yaml");
  const test::RunResult full = run("-o " + (dir / "full.yaml").string() + " " + good + " " + good);
  EXPECT_EQ(full.status, 2) << full.output;
  EXPECT_NE(full.output.find("full.yaml: write failed"), std::string::npos) << full.output;
  EXPECT_EQ(run(good).status, 2);
  EXPECT_EQ(run("--config " + (dir / "bad.yaml").string() + " " + good + " " + good).status, 2);
  EXPECT_NE(run("--config " + (dir / "bad.yaml").string() + " " + good + " " + good).output.find("nonsense_key"),
            std::string::npos);
}

// config/fusion.yaml is the single source of the fusion's defaults: it lists every key, and
// its values are exactly FusionParams{} (which the tests and the tools use without a file).
TEST(FusionParamsFile, ListsEveryKeyWithTheDefaultsTheCodeUses) {
  const std::string path = std::string(MRSLAM_SOURCE_DIR) + "/config/fusion.yaml";
  const auto defaults = fusionParamValues(FusionParams{});
  const auto from_file = fusionParamValues(loadFusionParams(path));
  std::ifstream in(path);
  std::set<std::string> listed;
  for (std::string line; std::getline(in, line);) {
    const size_t colon = line.find(':');
    if (!line.empty() && std::isalpha(static_cast<unsigned char>(line[0])) && colon != std::string::npos)
      listed.insert(line.substr(0, colon));
  }
  for (const auto& [key, value] : defaults) {
    EXPECT_TRUE(listed.count(key)) << key << " is not in " << path;
    EXPECT_EQ(from_file.at(key), value) << key;
  }
  EXPECT_EQ(listed.size(), defaults.size());
}

TEST(FusionParamsFile, RefusesUnknownKeysBadTypesAndOutOfRangeValuesNamingTheKey) {
  const fs::path dir = tempDir();
  const std::string path = (dir / "fusion.yaml").string();
  auto refusal = [&](const std::string& text) {
    std::ofstream(path) << text;
    try {
      loadFusionParams(path);
    } catch (const ParamsError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(refusal("min_acceptence: 0.9\n").find("unknown parameter 'min_acceptence'"), std::string::npos);
  EXPECT_NE(refusal("min_acceptance: high\n").find("'min_acceptance' has an invalid value"), std::string::npos);
  EXPECT_NE(refusal("min_acceptance: 1.5\n").find("'min_acceptance' 1.5 is outside [0, 1]"), std::string::npos);
  EXPECT_NE(refusal("coarse_max_cells: 4\n").find("'coarse_max_cells'"), std::string::npos);
  EXPECT_NE(refusal("max_entropy_increase: .nan\n").find("'max_entropy_increase'"), std::string::npos);
  EXPECT_EQ(refusal("min_acceptance: 0.9\n"), "accepted");
  fs::remove_all(dir);
}
