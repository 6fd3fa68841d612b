// mrslam_merge: offline map fusion of map_server maps, no ROS master needed.
//
//   mrslam_merge [--json] [-o merged.yaml [--png]] [--config fusion.yaml] [--held X,Y,YAW]
//                A.yaml B.yaml [C.yaml ...]
//
// -o writes the merged map (map_server yaml + pgm, or png with --png) in A's frame;
// --octomap writes it as an OctoMap (octomap::OcTree binary .bt, walls as 0.5 m columns).
// Every map after the first is aligned to A. With three or more maps, a map that does not
// match A directly is chained through any map already accepted (B in A and C in B give C
// in A). --held gives the pose of B's frame in A's (m, m, rad) that a merger held when it
// estimated B against A: the search verifies it too, so a merger's recorded estimate
// (estimate_record.h) replays exactly. Exit status: 0 when the run completed (rejected merges included), 2 on bad input.
#include <cmath>
#include <cstdio>
#include <opencv2/core/utils/logger.hpp>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "mrslam/fusion/estimate_record.h"
#include "mrslam/fusion/fusion_params_io.h"
#include "mrslam/fusion/grid_merge.h"
#include "mrslam/fusion/map_fusion.h"
#include "mrslam/map_io.h"
#include "mrslam/octomap_export.h"

namespace {

using mrslam::OccupancyGrid;
using mrslam::Pose2D;
namespace fusion = mrslam::fusion;

constexpr const char* kUsage =
    "usage: mrslam_merge [--json] [-o merged.yaml [--png]] [--octomap merged.bt] [--config fusion.yaml] [--timing]\n"
    "                    [--held X,Y,YAW] A.yaml B.yaml [C.yaml ...]\n";

int badInput(const std::string& message) {
  std::cerr << "mrslam_merge: " << message << "\n";
  return 2;
}

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) < 0x20) continue;
    out += c;
  }
  return out + "\"";
}

// Every check's figure (verification.h), so a user sees how close a verdict was; a figure
// that is not finite (the lever of a pose that shares no wall) is written as null, which JSON
// can hold.
std::string jsonChecks(const fusion::Verdict& v) {
  const std::pair<const char*, double> figures[] = {
      {"wall_agreement", v.wall_agreement},     {"shared_wall_m", v.shared_wall_m},
      {"shared_wall_fraction", v.shared_wall_fraction}, {"entropy_increase", v.entropy_increase},
      {"distinctiveness", v.distinctiveness},   {"ambiguity", v.ambiguity},
      {"seen_through", v.seen_through}, {"lever", v.lever}};
  std::string out;
  for (const auto& [key, value] : figures) {
    char number[32] = "null";
    if (std::isfinite(value)) std::snprintf(number, sizeof number, "%.4f", value);
    out += (out.empty() ? "\"" : ", \"") + std::string(key) + "\": " + number;
  }
  return out;
}

struct Outcome {
  std::optional<Pose2D> pose_in_a;  // set once accepted (directly or through a chain)
  fusion::FusionResult last;        // the latest attempt (for V, time and the reason)
  double time_ms = 0;               // all attempts for this map
  int via = 0;                      // index of the map it was aligned to
};

}  // namespace

int main(int argc, char** argv) {
  // Our own messages name the file and the problem; OpenCV's warnings would repeat them.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
  bool json = false, png = false, timing = false;
  std::string output, config, octomap;
  std::optional<Pose2D> held;  // of the second map in the first's frame
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--json") {
      json = true;
    } else if (arg == "--png") {
      png = true;
    } else if (arg == "--timing") {
      timing = true;
    } else if (arg == "-o" || arg == "--config" || arg == "--octomap") {
      if (i + 1 >= argc) return badInput(arg + " needs a file name\n" + kUsage);
      (arg == "-o" ? output : arg == "--config" ? config : octomap) = argv[++i];
    } else if (arg == "--held") {
      if (i + 1 >= argc || !(held = fusion::parsePoseText(argv[++i])))
        return badInput("--held needs a pose X,Y,YAW (m, m, rad)\n" + std::string(kUsage));
    } else if (arg == "-h" || arg == "--help") {
      std::cout << kUsage;
      return 0;
    } else if (!arg.empty() && arg[0] == '-') {
      return badInput("unknown option " + arg + "\n" + kUsage);
    } else {
      files.push_back(arg);
    }
  }
  if (files.size() < 2) return badInput(std::string("need at least two maps\n") + kUsage);

  fusion::FusionParams params;
  try {
    if (!config.empty()) params = fusion::loadFusionParams(config);
  } catch (const std::exception& e) {
    return badInput(e.what());
  }
  std::vector<OccupancyGrid> maps;
  for (const std::string& file : files) {
    try {
      maps.push_back(mrslam::loadMap(file));
    } catch (const std::exception& e) {
      return badInput(e.what());
    }
    const std::string why = fusion::checkFusable(maps.back(), params);
    if (!why.empty()) return badInput(file + ": " + why);
    const double ratio = maps.back().resolution / maps.front().resolution;
    if (ratio > params.max_resolution_ratio || ratio < 1.0 / params.max_resolution_ratio)
      return badInput(file + ": resolution " + std::to_string(maps.back().resolution) +
                      " is too far from the first map's " + std::to_string(maps.front().resolution));
  }

  // Align every map to A, then retry the rejected ones against maps accepted meanwhile.
  std::vector<Outcome> outcomes(maps.size());
  outcomes[0].pose_in_a = Pose2D{};
  std::vector<std::vector<bool>> tried(maps.size(), std::vector<bool>(maps.size(), false));
  for (bool progress = true; progress;) {
    progress = false;
    for (size_t i = 1; i < maps.size(); ++i) {
      for (size_t j = 0; j < maps.size() && !outcomes[i].pose_in_a; ++j) {
        if (j == i || !outcomes[j].pose_in_a || tried[i][j]) continue;
        tried[i][j] = true;
        fusion::FusionResult r;
        try {
          r = fusion::alignMaps(maps[j], maps[i], params, i == 1 && j == 0 ? held : std::nullopt);
        } catch (const std::exception& e) {
          return badInput(files[i] + ": " + e.what());
        }
        outcomes[i].last = r;
        if (timing) {
          std::fprintf(stderr, "%s against %s:", files[i].c_str(), files[j].c_str());
          for (const auto& [name, ms] : r.stage_ms) std::fprintf(stderr, " %s %.1f ms,", name.c_str(), ms);
          std::fprintf(stderr, " total %.1f ms\n", r.time_ms);
        }
        outcomes[i].time_ms += r.time_ms;
        if (r.accepted) {
          outcomes[i].pose_in_a = outcomes[j].pose_in_a->compose(r.pose);
          outcomes[i].via = static_cast<int>(j);
          progress = true;
        }
      }
    }
  }

  for (size_t i = 1; i < maps.size(); ++i) {
    const Outcome& o = outcomes[i];
    const Pose2D pose = o.pose_in_a.value_or(o.last.pose);
    if (json) {
      std::printf("{\"map\": %s, \"accepted\": %s, \"x\": %.10g, \"y\": %.10g, \"yaw\": %.8g, "
                  "\"acceptance\": %.4f, %s, \"time_ms\": %.1f%s%s}\n",
                  jsonString(files[i]).c_str(), o.pose_in_a ? "true" : "false", pose.x, pose.y, pose.yaw,
                  o.last.verdict.acceptance, jsonChecks(o.last.verdict).c_str(), o.time_ms,
                  o.pose_in_a ? (", \"via\": " + jsonString(files[o.via])).c_str() : "",
                  o.pose_in_a ? "" : (", \"reason\": " + jsonString(o.last.verdict.reason)).c_str());
    } else if (o.pose_in_a) {
      std::printf("%s: accepted  x=%.3f m  y=%.3f m  yaw=%.2f deg  V=%.3f  (%.0f ms, via %s)\n",
                  files[i].c_str(), pose.x, pose.y, pose.yaw * 180.0 / M_PI, o.last.verdict.acceptance,
                  o.time_ms, files[o.via].c_str());
    } else {
      std::printf("%s: rejected  (%s; %.0f ms)\n", files[i].c_str(), o.last.verdict.reason.c_str(), o.time_ms);
    }
  }

  if (!output.empty() || !octomap.empty()) {
    std::vector<fusion::PlacedGrid> placed;
    for (size_t i = 1; i < maps.size(); ++i)
      if (outcomes[i].pose_in_a) placed.push_back({&maps[i], *outcomes[i].pose_in_a});
    try {
      const OccupancyGrid merged = fusion::mergeGrids(maps[0], placed);
      if (!output.empty()) mrslam::saveMap(merged, output, png ? ".png" : ".pgm");
      if (!octomap.empty()) mrslam::saveOctomap(merged, octomap);
    } catch (const std::exception& e) {
      return badInput(e.what());
    }
  }
  return 0;
}
