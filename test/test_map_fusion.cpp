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
#include "mrslam/fusion/fusion_params_io.h"
#include "mrslam/fusion/map_fusion.h"
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

fs::path tempDir() {
  fs::path dir = fs::temp_directory_path() / ("mrslam_fusion_test_" + std::to_string(::getpid()));
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
