#include "mrslam/fusion/estimate_record.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "mrslam/map_io.h"

namespace mrslam::fusion {
namespace {

namespace fs = std::filesystem;

bool isPlainName(const std::string& name) {
  if (name.empty()) return false;
  for (char c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

// One line of estimates.tsv: reasons are free text, so tabs and line breaks become spaces.
std::string recordLine(const std::optional<Pose2D>& held, const FusionResult& result, double wall_s) {
  char numbers[256];
  std::snprintf(numbers, sizeof(numbers), "%.3f\t%d\t%.17g\t%.17g\t%.17g\t%.4f\t%.2f\t", wall_s,
                result.accepted ? 1 : 0, result.pose.x, result.pose.y, result.pose.yaw,
                result.verdict.acceptance, result.verdict.shared_wall_m);
  const std::string line = numbers + (held ? poseText(*held) : "-");
  std::string reason = result.verdict.reason.empty() ? "-" : result.verdict.reason;
  for (char& c : reason)
    if (c == '\t' || c == '\n' || c == '\r') c = ' ';
  return line + "\t" + reason + "\n";
}

}  // namespace

std::string poseText(const Pose2D& pose) {
  char text[96];
  std::snprintf(text, sizeof(text), "%.17g,%.17g,%.17g", pose.x, pose.y, pose.yaw);
  return text;
}

std::optional<Pose2D> parsePoseText(const std::string& text) {
  Pose2D pose;
  int used = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%n", &pose.x, &pose.y, &pose.yaw, &used) != 3 ||
      used != static_cast<int>(text.size()) || !std::isfinite(pose.x) || !std::isfinite(pose.y) ||
      !std::isfinite(pose.yaw))
    return std::nullopt;
  return pose;
}

void recordEstimate(const std::string& dir, const std::string& peer, const std::string& via, const OccupancyGrid& a,
                    const OccupancyGrid& b, const std::optional<Pose2D>& held, const FusionResult& result,
                    double wall_s) {
  if (!isPlainName(peer)) throw std::invalid_argument("estimate record id '" + peer + "' is not [A-Za-z0-9_]+");
  if (!via.empty() && !isPlainName(via))
    throw std::invalid_argument("estimate record id '" + via + "' is not [A-Za-z0-9_]+");
  const fs::path where = via.empty() ? fs::path(dir) / peer : fs::path(dir) / peer / ("via_" + via);
  std::error_code error;
  fs::create_directories(where, error);
  if (error) throw MapIoError(where.string() + ": cannot create the record directory: " + error.message());
  saveMap(a, (where / "latest_a.yaml").string());
  saveMap(b, (where / "latest_b.yaml").string());
  if (result.accepted) {
    saveMap(a, (where / "accepted_a.yaml").string());
    saveMap(b, (where / "accepted_b.yaml").string());
  }
  const fs::path table = where / "estimates.tsv";
  const bool fresh = !fs::exists(table);
  std::ofstream out(table, std::ios::app);
  if (fresh) out << kEstimateRecordHeader;
  out << recordLine(held, result, wall_s);
  if (!out) throw MapIoError(table.string() + ": cannot append the estimate");
}

}  // namespace mrslam::fusion
