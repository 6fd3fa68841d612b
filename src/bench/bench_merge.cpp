// mrslam_bench_merge: map-merge accuracy and speed of mrslam and its peers on real data.
//
// Pairs, with ground truth from their construction only (see pair_maker.h):
//  - "window": two time windows of one corrected CARMEN log (Intel, ACES, Freiburg 079/101),
//    ray-cast along the reference poses with random-walk drift; B in a random frame;
//  - "crop": two overlapping crops of a real map (maps/reference and UT GDC floor 1),
//    B re-rasterised in a random frame;
//  - "multi-run": real maps of one place from separate mapping runs (maps/halmstad_dev), truth
//    and "correct" from the data set's annotated corners (multi_run_pairs.h);
//  - "none": maps of two different buildings, which must be rejected;
//  - "whole-vs-crop": a whole reference map against a crop of another building, both orders
//    (the shape of regressions/cross_building_accept), which must be rejected too.
// Random frames: yaw uniform in [0, 360) degrees, shift uniform in +-40 m.
// Overlap: the share of the smaller map's known cells that the other map also knows.
// Correct (same-run pairs): |yaw error| <= 1 degree and the centre of B's grid placed within 2 cells.
// Everything runs on one thread (cv::setNumThreads(1)), pair after pair, same pairs per tool;
// --repeat N times mrslam on each pair by the fastest of N calls.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "mrslam/bench/multi_run_pairs.h"
#include "mrslam/bench/pair_maker.h"
#include "mrslam/bench/peers.h"
#include "mrslam/fusion/fusion_params_io.h"
#include "mrslam/fusion/map_fusion.h"
#include "mrslam/map_io.h"

using namespace mrslam;

namespace {

constexpr double kDeg = M_PI / 180.0;
// The multi-run maps state no resolution; their README's figures are in cells, so any works.
constexpr double kMultiRunResolution = 0.05;

std::shared_ptr<const OccupancyGrid> share(OccupancyGrid grid) {
  return std::make_shared<const OccupancyGrid>(std::move(grid));
}

struct Pair {
  std::string name, kind;  // kind: window | crop | multi-run | none | whole-vs-crop
  std::shared_ptr<const OccupancyGrid> a, b;  // shared: multi-run pairs reuse each run's map
  Pose2D truth;
  double overlap = 0;
  const bench::MultiRunPair* run = nullptr;  // multi-run pairs: the annotated corners
};

// Pairs of two different buildings: any accepted pose is a false accept.
bool foreign(const Pair& p) { return p.kind == "none" || p.kind == "whole-vs-crop"; }

struct Outcome {
  bool accepted = false, correct = false;
  bool pose_right = false;  // the pose found passes the correctness rule, accepted or not
  double yaw_err_deg = 0, cells_err = 0, time_ms = 0;
  std::string reason;  // why mrslam rejected (empty for the peers)
  fusion::Verdict verdict;  // mrslam's verification figures
};

std::string band(const Pair& p) {
  if (p.kind == "none") return "no overlap";
  if (p.kind == "whole-vs-crop") return "whole map vs crop of another";
  if (p.kind == "multi-run") return "multi-run";
  return p.overlap < 0.5 ? "25-50 %" : (p.overlap < 0.75 ? "50-75 %" : "75-100 %");
}

Outcome judge(const Pair& p, bool accepted, const Pose2D& pose, double time_ms) {
  Outcome o;
  o.accepted = accepted, o.time_ms = time_ms;
  if (p.run) {  // the data set's own rule, on the annotated corners (multi_run_pairs.h)
    const bench::MultiRunJudgement j = bench::judgeMultiRun(*p.run, pose, p.a->resolution);
    o.yaw_err_deg = j.yaw_err_deg, o.cells_err = j.corner_err_cells;
    o.pose_right = j.correct;
    o.correct = accepted && o.pose_right;
    return o;
  }
  double cx, cy, ex, ey, tx, ty;
  p.b->origin.apply(p.b->width * p.b->resolution / 2, p.b->height * p.b->resolution / 2, cx, cy);
  pose.apply(cx, cy, ex, ey);
  p.truth.apply(cx, cy, tx, ty);
  o.yaw_err_deg = std::abs(std::remainder(pose.yaw - p.truth.yaw, 2 * M_PI)) / kDeg;
  o.cells_err = std::hypot(ex - tx, ey - ty) / p.a->resolution;
  o.pose_right = !foreign(p) && o.yaw_err_deg <= 1.0 && o.cells_err <= 2.0;
  o.correct = accepted && o.pose_right;
  return o;
}

Pose2D randomFrame(std::mt19937& rng) {
  std::uniform_real_distribution<double> yaw(0, 2 * M_PI), shift(-40, 40);
  const double x = shift(rng), y = shift(rng);
  return {x, y, yaw(rng)};
}

struct Builder {
  std::string data;
  std::mt19937 rng;
  bench::RaycastParams raycast;
  std::map<std::string, std::vector<bench::LaserScan2D>> logs;
  std::map<std::string, OccupancyGrid> maps;

  const std::vector<bench::LaserScan2D>& log(const std::string& name) {
    auto it = logs.find(name);
    if (it == logs.end())
      it = logs.emplace(name, bench::readCarmenScans(data + "/logs/carmen_corrected/" + name + "-corrected.log.gz")).first;
    return it->second;
  }
  const OccupancyGrid& map(const std::string& path) {
    auto it = maps.find(path);
    if (it == maps.end()) it = maps.emplace(path, loadMap(data + "/maps/" + path + ".yaml")).first;
    return it->second;
  }

  // A random time window of a log, in a frame `frame` (identity for map A).
  OccupancyGrid window(const std::string& name, const Pose2D& frame, std::string& label) {
    const auto& scans = log(name);
    const size_t n = scans.size();
    std::uniform_real_distribution<double> length(0.25, 0.6), start(0, 1);
    const size_t len = static_cast<size_t>(length(rng) * n);
    const size_t first = static_cast<size_t>(start(rng) * (n - len));
    label = name + "[" + std::to_string(first) + "," + std::to_string(first + len) + ")";
    return bench::raycastMap(scans, first, first + len, frame, raycast, rng);
  }
  OccupancyGrid crop(const std::string& path, std::string& label) {
    const OccupancyGrid& g = map(path);
    std::uniform_real_distribution<double> size(0.45, 0.8), pos(0, 1);
    const int w = static_cast<int>(size(rng) * g.width), h = static_cast<int>(size(rng) * g.height);
    const int c0 = static_cast<int>(pos(rng) * (g.width - w)), r0 = static_cast<int>(pos(rng) * (g.height - h));
    label = path + "(" + std::to_string(c0) + "," + std::to_string(r0) + " " + std::to_string(w) + "x" + std::to_string(h) + ")";
    return bench::trimUnknown(bench::cropGrid(g, c0, r0, w, h));
  }
};

// The pairs of one seed: per_band overlapping pairs per overlap band (half time windows, half
// crops, evenly over the sources), then `negatives` pairs of two different buildings.
std::vector<Pair> makePairs(Builder& builder, int per_band, int negatives) {
  const std::vector<std::string> logs = {"intel", "aces", "freiburg-079", "freiburg-101"};
  // Crops: the reference maps and a robot-built floor. Not willow (its walls are grey: under
  // map_server's trinary rule it has 544 obstacle cells) nor rilo (its free_thresh 0.25 makes
  // the unknown grey 205 free, so it has no unknown space): no tool can be judged on those.
  const std::vector<std::string> crop_maps = {"reference/intel", "reference/aces", "reference/freiburg-079",
                                              "reference/freiburg-101", "robot_built/gdc_floor1"};
  std::vector<Pair> pairs;
  // Overlapping pairs: half time windows, half crops, evenly over the bands and sources.
  std::map<std::string, int> filled;  // kind + band -> count
  const int per_kind = per_band / 2, wanted = per_kind * 2 * 3;
  // Checked before each attempt: with no pair wanted, nothing is ray-cast (4000 attempts took
  // 4 minutes and kept none).
  for (int attempt = 0; attempt < 4000 && static_cast<int>(pairs.size()) < wanted; ++attempt) {
    const bool want_window = attempt % 2 == 0;
    const std::string kind = want_window ? "window" : "crop";
    Pair p;
    p.kind = kind;
    std::string la, lb;
    if (want_window) {
      const std::string& log = logs[(attempt / 2) % logs.size()];
      p.truth = randomFrame(builder.rng);
      p.a = share(builder.window(log, Pose2D{}, la));
      p.b = share(builder.window(log, p.truth, lb));
    } else {
      const std::string& path = crop_maps[(attempt / 2) % crop_maps.size()];
      p.a = share(builder.crop(path, la));
      const OccupancyGrid b = builder.crop(path, lb);
      p.truth = randomFrame(builder.rng);
      p.b = share(bench::reframeGrid(b, p.truth));
    }
    p.overlap = bench::knownOverlap(*p.a, *p.b, p.truth);
    if (p.overlap < 0.25) continue;
    const std::string key = kind + band(p);
    if (filled[key] >= per_kind) continue;
    ++filled[key];
    p.name = la + " + " + lb;
    pairs.push_back(std::move(p));
  }
  // Non-overlapping pairs: two different buildings.
  std::uniform_int_distribution<size_t> pick(0, logs.size() - 1);
  for (int k = 0; k < negatives; ++k) {
    Pair p;
    p.kind = "none";
    std::string la, lb;
    const size_t i = pick(builder.rng);
    size_t j = pick(builder.rng);
    while (j == i) j = pick(builder.rng);
    p.truth = randomFrame(builder.rng);
    if (k % 2 == 0) {
      p.a = share(builder.window(logs[i], Pose2D{}, la));
      p.b = share(builder.window(logs[j], p.truth, lb));
    } else {
      p.a = share(builder.crop(crop_maps[i], la));
      p.b = share(bench::reframeGrid(builder.crop(k % 4 == 1 ? "robot_built/gdc_floor1" : crop_maps[j], lb), p.truth));
    }
    p.name = la + " + " + lb;
    pairs.push_back(std::move(p));
  }
  return pairs;
}

// Foreign pairs of the kind that slipped through before (regressions/cross_building_accept): a
// whole reference map against a crop of another building (about 700 x 700 cells, a random
// frame), in both orders, `per_order` times for every ordered pair of buildings.
std::vector<Pair> makeWholeVsCropPairs(Builder& builder, int per_order) {
  const std::vector<std::string> maps = {"reference/intel", "reference/aces", "reference/freiburg-079",
                                         "reference/freiburg-101", "robot_built/gdc_floor1"};
  std::vector<Pair> pairs;
  std::map<std::string, std::shared_ptr<const OccupancyGrid>> whole_maps;  // one copy per map, not per pair
  for (const std::string& m : maps) whole_maps[m] = share(OccupancyGrid(builder.map(m)));
  std::uniform_real_distribution<double> pos(0, 1);
  for (int k = 0; k < per_order; ++k)
    for (const std::string& whole : maps)
      for (const std::string& other : maps) {
        if (whole == other) continue;
        const OccupancyGrid& g = builder.map(other);
        const int w = std::min(700, g.width), h = std::min(700, g.height);
        const int c0 = static_cast<int>(pos(builder.rng) * (g.width - w)), r0 = static_cast<int>(pos(builder.rng) * (g.height - h));
        const std::string crop_label = other + "(" + std::to_string(c0) + "," + std::to_string(r0) + " " +
                                       std::to_string(w) + "x" + std::to_string(h) + ")";
        const auto crop = share(bench::trimUnknown(bench::cropGrid(g, c0, r0, w, h)));
        for (const bool whole_first : {true, false}) {
          Pair p;
          p.kind = "whole-vs-crop";
          p.truth = randomFrame(builder.rng);
          if (whole_first) {
            p.a = whole_maps[whole];
            p.b = share(bench::reframeGrid(*crop, p.truth));
            p.name = whole + " + " + crop_label;
          } else {
            p.a = crop;
            p.b = share(bench::reframeGrid(*whole_maps[whole], p.truth));
            p.name = crop_label + " + " + whole;
          }
          pairs.push_back(std::move(p));
        }
      }
  return pairs;
}

// Up to `count` of the annotated multi-run pairs (all when count >= their number; otherwise an
// even spread over the list, so both places and many runs take part).
std::vector<Pair> makeMultiRunPairs(const std::string& dir, const std::vector<bench::MultiRunPair>& runs, int count) {
  std::map<std::string, std::shared_ptr<const OccupancyGrid>> maps;
  auto load = [&](const std::string& name) {
    auto& m = maps[name];
    if (!m) m = share(bench::loadRunMap(dir + "/" + name + ".png", kMultiRunResolution));
    return m;
  };
  std::vector<Pair> pairs;
  const size_t n = runs.size(), wanted = std::min(n, static_cast<size_t>(std::max(0, count)));
  for (size_t k = 0; k < wanted; ++k) {
    const bench::MultiRunPair& r = runs[k * n / wanted];
    Pair p;
    p.kind = "multi-run", p.run = &r, p.truth = r.truth;
    p.a = load(r.map_a), p.b = load(r.map_b);
    p.overlap = bench::knownOverlap(*p.a, *p.b, p.truth);
    p.name = r.map_a + " + " + r.map_b;
    pairs.push_back(std::move(p));
  }
  return pairs;
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = "../shared/data", csv_path, config, dump_dir;
  int per_band = 24, negatives = 18, multi_run = 188, whole_vs_crop = 2, repeat = 1;
  std::vector<unsigned> seeds = {2026};
  double drift_scale = 1.0;
  bool run_mrpt = true, large = true, only_mrslam = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) { std::cerr << arg << " needs a value\n"; std::exit(2); }
      return argv[++i];
    };
    if (arg == "--data") data = next();
    else if (arg == "--per-band") per_band = std::stoi(next());
    else if (arg == "--negatives") negatives = std::stoi(next());
    else if (arg == "--seed") seeds = {static_cast<unsigned>(std::stoul(next()))};
    else if (arg == "--seeds") {  // e.g. 11,2026,7: the pairs of every seed, pooled in one table
      seeds.clear();
      std::stringstream list(next());
      for (std::string item; std::getline(list, item, ',');) seeds.push_back(static_cast<unsigned>(std::stoul(item)));
      if (seeds.empty()) { std::cerr << "--seeds needs a comma-separated list\n"; return 2; }
    }
    else if (arg == "--multi-run") multi_run = std::stoi(next());
    else if (arg == "--whole-vs-crop") whole_vs_crop = std::stoi(next());
    else if (arg == "--csv") csv_path = next();
    else if (arg == "--drift-scale") drift_scale = std::stod(next());
    else if (arg == "--config") config = next();
    else if (arg == "--dump-failures") dump_dir = next();
    else if (arg == "--repeat") repeat = std::max(1, std::stoi(next()));
    else if (arg == "--only-mrslam") only_mrslam = true;
    else if (arg == "--no-mrpt") run_mrpt = false;
    else if (arg == "--no-large") large = false;
    else {
      std::cerr << "usage: mrslam_bench_merge [--data DIR] [--per-band N] [--negatives N] [--seed N | --seeds A,B,..] "
                   "[--csv FILE] [--config fusion.yaml] [--no-mrpt] [--no-large] [--only-mrslam]\n"
                   "                          [--drift-scale F] [--multi-run N] [--whole-vs-crop N]\n"
                   "                          [--dump-failures DIR] [--repeat N]\n";
      return 2;
    }
  }
  if (!dump_dir.empty()) std::filesystem::create_directories(dump_dir);
  cv::setNumThreads(1);
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
  fusion::FusionParams params;
  if (!config.empty()) params = fusion::loadFusionParams(config);

  Builder builder{data, std::mt19937(seeds.front()), {}, {}, {}};
  builder.raycast.drift_sigma_xy *= drift_scale;
  builder.raycast.drift_sigma_yaw *= drift_scale;
  const std::vector<std::string> bands = {"25-50 %", "50-75 %", "75-100 %"};

  // Each seed draws its own pairs; with several seeds the tables pool them.
  std::vector<Pair> pairs;
  const auto t_gen = std::chrono::steady_clock::now();
  std::string seed_list;
  for (const unsigned seed : seeds) {
    builder.rng.seed(seed);
    for (Pair& p : makePairs(builder, per_band, negatives)) {
      if (seeds.size() > 1) p.name = "seed " + std::to_string(seed) + ": " + p.name;
      pairs.push_back(std::move(p));
    }
    seed_list += (seed_list.empty() ? "" : ", ") + std::to_string(seed);
  }
  builder.rng.seed(seeds.front());
  for (Pair& p : makeWholeVsCropPairs(builder, whole_vs_crop)) pairs.push_back(std::move(p));
  const std::string multi_run_dir = data + "/maps/halmstad_dev";
  const std::vector<bench::MultiRunPair> runs =
      multi_run > 0 ? bench::readMultiRunPairs(multi_run_dir, kMultiRunResolution) : std::vector<bench::MultiRunPair>{};
  for (Pair& p : makeMultiRunPairs(multi_run_dir, runs, multi_run)) pairs.push_back(std::move(p));
  std::printf("# Map-merge benchmark (seed%s %s): %zu pairs built in %.0f s\n\n", seeds.size() > 1 ? "s" : "",
              seed_list.c_str(), pairs.size(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t_gen).count());

  std::map<std::string, std::vector<double>> stage_times;  // mrslam's time per stage
  std::vector<std::pair<std::string, double>> last_stages;  // ...and those of its last pair
  using Tool = std::function<Outcome(const Pair&)>;
  std::vector<std::pair<std::string, Tool>> tools = {
      {"mrslam", [&](const Pair& p) {
         // --repeat N: the fastest of N calls (on a virtual machine two runs' medians differed by
         // a fifth); every call must give the same answer.
         auto r = fusion::alignMaps(*p.a, *p.b, params);
         for (int k = 1; k < repeat; ++k) {
           auto again = fusion::alignMaps(*p.a, *p.b, params);
           if (again.accepted != r.accepted || again.cells.theta != r.cells.theta || again.cells.t != r.cells.t) {
             std::fprintf(stderr, "mrslam_bench_merge: %s: call %d gave another answer\n", p.name.c_str(), k + 1);
             std::exit(1);
           }
           if (again.time_ms < r.time_ms) r = std::move(again);
         }
         Outcome o = judge(p, r.accepted, r.pose, r.time_ms);
         o.reason = r.verdict.reason;
         for (const auto& [stage, ms] : r.stage_ms) stage_times[stage].push_back(ms);
         last_stages = r.stage_ms;
         o.verdict = r.verdict;
         if (!dump_dir.empty() && (foreign(p) ? o.accepted : !o.correct)) {
           const std::string stem = dump_dir + "/pair" + std::to_string(&p - pairs.data());
           saveMap(*p.a, stem + "_a.yaml");
           saveMap(*p.b, stem + "_b.yaml");
           std::ofstream(stem + "_truth.txt") << p.truth.x << " " << p.truth.y << " " << p.truth.yaw << "  # " << p.name << "\n";
         }
         return o;
       }},
      {"akaze (m-explore style)", [&](const Pair& p) {
         const auto r = bench::alignWithAkaze(*p.a, *p.b);
         return judge(p, r.accepted, r.pose, r.time_ms);
       }},
  };
  if (only_mrslam) tools.resize(1);
  if (run_mrpt && !only_mrslam)
    tools.push_back({"mrpt CGridMapAligner", [&](const Pair& p) {
                       const auto r = bench::alignWithMrpt(*p.a, *p.b);
                       return judge(p, r.accepted, r.pose, r.time_ms);
                     }});

  std::ofstream csv;
  if (!csv_path.empty()) {
    csv.open(csv_path);
    csv << "tool,kind,band,overlap,pair,a_cells,b_cells,accepted,correct,yaw_err_deg,cells_err,time_ms,reason,V,wall_agreement,shared_wall_m,entropy_increase,distinctiveness,shared_wall_fraction,ambiguity,seen_through,lever,pose_right\n";
  }
  for (const auto& [tool_name, tool] : tools) {
    std::map<std::string, std::vector<Outcome>> by_band;
    std::vector<double> times, overlapping_times;  // all pairs; pairs that overlap
    for (const Pair& p : pairs) {
      const Outcome o = tool(p);
      by_band[band(p)].push_back(o);
      times.push_back(o.time_ms);
      if (!foreign(p) && !p.run) overlapping_times.push_back(o.time_ms);
      if (csv) {
        csv << '"' << tool_name << "\"," << p.kind << ",\"" << band(p) << "\"," << p.overlap << ",\"" << p.name << "\","
            << p.a->width << "x" << p.a->height << "," << p.b->width << "x" << p.b->height << "," << o.accepted << ","
            << o.correct << "," << o.yaw_err_deg << "," << o.cells_err << "," << o.time_ms << ",\"" << o.reason << "\"," << o.verdict.acceptance << ","
            << o.verdict.wall_agreement << "," << o.verdict.shared_wall_m << "," << o.verdict.entropy_increase << ","
            << o.verdict.distinctiveness << "," << o.verdict.shared_wall_fraction << "," << o.verdict.ambiguity;
        csv << "," << o.verdict.seen_through << "," << o.verdict.lever << "," << o.pose_right << "\n";
      }
    }
    std::printf("## %s\n\n| overlap | pairs | correct | rejected | wrong accepts | false accepts | median ms | p95 ms |\n"
                "|---|---|---|---|---|---|---|---|\n", tool_name.c_str());
    int all_pairs = 0, all_correct = 0, all_wrong = 0;
    for (const std::string& b : {bands[0], bands[1], bands[2], std::string("multi-run"), std::string("no overlap"),
                                 std::string("whole map vs crop of another")}) {
      auto& v = by_band[b];
      if (v.empty()) continue;
      int correct = 0, rejected = 0, wrong = 0;
      std::vector<double> t;
      for (const Outcome& o : v) {
        correct += o.correct, rejected += !o.accepted, wrong += o.accepted && !o.correct;
        t.push_back(o.time_ms);
      }
      std::sort(t.begin(), t.end());
      const bool none = b == "no overlap" || b == "whole map vs crop of another";
      if (!none && b != "multi-run") all_pairs += v.size(), all_correct += correct, all_wrong += wrong;
      std::printf("| %s | %zu | %s | %d | %s | %s | %.0f | %.0f |\n", b.c_str(), v.size(),
                  none ? "-" : (std::to_string(correct) + " (" + std::to_string(100 * correct / int(v.size())) + " %)").c_str(),
                  rejected, none ? "-" : std::to_string(wrong).c_str(), none ? std::to_string(wrong).c_str() : "-",
                  t[t.size() / 2], t[std::min(t.size() - 1, static_cast<size_t>(0.95 * t.size()))]);
    }
    if (times.empty()) continue;
    std::sort(times.begin(), times.end());
    std::sort(overlapping_times.begin(), overlapping_times.end());
    auto median = [](const std::vector<double>& t) { return t[t.size() / 2]; };
    auto p95 = [](const std::vector<double>& t) { return t[std::min(t.size() - 1, static_cast<size_t>(0.95 * t.size()))]; };
    if (!overlapping_times.empty())
      std::printf("| all same-run overlapping | %d | %d (%.1f %%) | | %d | | %.0f | %.0f |\n", all_pairs, all_correct,
                  100.0 * all_correct / std::max(1, all_pairs), all_wrong, median(overlapping_times), p95(overlapping_times));
    std::printf("\nAll %zu pairs, overlapping or not: median %.0f ms, p95 %.0f ms.\n\n", times.size(), median(times), p95(times));
    if (const auto& runs = by_band["multi-run"]; !runs.empty()) {
      // What the search alone achieved: the pose the tool ended at, accepted or not.
      const auto right = std::count_if(runs.begin(), runs.end(), [](const Outcome& o) { return o.pose_right; });
      std::printf("Multi-run pairs whose pose passes the data set's rule, accepted or not: %ld of %zu.\n\n",
                  static_cast<long>(right), runs.size());
    }
    if (tool_name == "mrslam") {
      std::printf("mrslam median ms per stage:");
      for (auto& [stage, v] : stage_times) {
        std::sort(v.begin(), v.end());
        std::printf(" %s %.1f,", stage.c_str(), v[v.size() / 2]);
      }
      std::printf("\n\n");
    }
    std::fflush(stdout);
  }

  if (large) {
    // One ~4000 x 4000 pair: the ACES reference map at 3.4x finer resolution (nearest
    // neighbour), A the whole map, B an 85 % crop in a random frame.
    const OccupancyGrid& aces = builder.map("reference/aces");
    const double factor = 3.4;
    OccupancyGrid big;
    big.resolution = aces.resolution / factor, big.origin = aces.origin;
    big.width = static_cast<int>(aces.width * factor), big.height = static_cast<int>(aces.height * factor);
    big.data.resize(static_cast<size_t>(big.width) * big.height);
    for (int r = 0; r < big.height; ++r)
      for (int c = 0; c < big.width; ++c) big.at(c, r) = aces.at(static_cast<int>(c / factor), static_cast<int>(r / factor));
    Pair p;
    p.kind = "crop", p.a = share(OccupancyGrid(big)), p.truth = randomFrame(builder.rng);
    p.b = share(bench::reframeGrid(bench::cropGrid(big, big.width * 15 / 100, 0, big.width * 85 / 100, big.height), p.truth));
    p.overlap = bench::knownOverlap(*p.a, *p.b, p.truth);
    std::printf("## Large pair: %d x %d and %d x %d cells (ACES at %.4f m, B's frame x %.3f y %.3f yaw %.4f)\n\n"
                "| tool | accepted | correct | ms |\n|---|---|---|---|\n",
                p.a->width, p.a->height, p.b->width, p.b->height, big.resolution, p.truth.x, p.truth.y, p.truth.yaw);
    for (const auto& [tool_name, tool] : tools) {
      if (tool_name.rfind("mrpt", 0) == 0) continue;  // minutes per run on this size; see the closing note
      const Outcome o = tool(p);
      std::printf("| %s | %s | %s | %.0f |\n", tool_name.c_str(), o.accepted ? "yes" : "no", o.correct ? "yes" : "no", o.time_ms);
    }
    // Where the time went: on a virtual machine whose balloon hands freed memory back to the
    // host, pages freed seconds ago cost many times more to fault in again, which shows in the
    // stages that allocate the most (the README's paragraph after the merge table).
    std::printf("\nmrslam ms per stage on this pair:");
    for (const auto& [stage, ms] : last_stages) std::printf(" %s %.0f,", stage.c_str(), ms);
    std::printf("\n");
  }
  return 0;
}
