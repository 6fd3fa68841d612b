#include "mrslam/bench/scan_fixed_frame.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace mrslam::bench {
namespace {

// Reference poses written to a bag and read back are the log's to within float rounding.
constexpr double kSamePoseM = 1e-6, kSamePoseRad = 1e-6;

bool samePose(const Pose2D& a, const Pose2D& b) {
  return std::abs(a.x - b.x) <= kSamePoseM && std::abs(a.y - b.y) <= kSamePoseM &&
         std::abs(Pose2D::normalizeAngle(a.yaw - b.yaw)) <= kSamePoseRad;
}

// The records of `log` the track has an estimate for (record index), with that estimate. A bag
// made from a window of the log restamps its scans (mrslam_log_to_bag), but carries each scan's
// reference pose as the log has it: the track's scans are found by their reference poses, in
// order (a robot standing still repeats a pose; its scans there are paired in turn).
using TrackRecords = std::vector<std::pair<size_t, Pose2D>>;
TrackRecords trackRecords(const slam::RobotLog& log, const RobotTrack& track) {
  TrackRecords out;
  size_t next = 0;
  for (const auto& [stamp, reference] : track.reference) {
    size_t k = next;
    while (k < log.records.size() && !(log.records[k].has_reference && samePose(log.records[k].reference, reference))) ++k;
    if (k == log.records.size()) continue;  // not a scan of this log
    next = k + 1;
    if (const auto estimate = track.estimate.find(stamp); estimate != track.estimate.end())
      out.emplace_back(k, estimate->second);
  }
  return out;
}

double median(std::vector<double> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Pairs (index into records_n, index into records_m) the reference puts on one place, in a
// seeded random order, at most params.max_tried of them.
std::vector<std::pair<size_t, size_t>> candidatePairs(const slam::RobotLog& log, const TrackRecords& records_n,
                                                      const TrackRecords& records_m, const ScanFixedParams& params) {
  std::vector<std::pair<size_t, size_t>> candidates;
  for (size_t a = 0; a < records_n.size(); ++a)
    for (size_t b = 0; b < records_m.size(); ++b) {
      const Pose2D& ra = log.records[records_n[a].first].reference;
      const Pose2D& rb = log.records[records_m[b].first].reference;
      if (std::hypot(rb.x - ra.x, rb.y - ra.y) <= params.relation.max_distance &&
          std::abs(Pose2D::normalizeAngle(rb.yaw - ra.yaw)) <= params.relation.max_turn)
        candidates.emplace_back(a, b);
    }
  std::mt19937 rng(params.seed);
  std::shuffle(candidates.begin(), candidates.end(), rng);
  if (candidates.size() > params.max_tried) candidates.resize(params.max_tried);
  return candidates;
}

// The scans of a track around its k-th: those within `reach` metres of path of it (by the
// track's own poses), each with its pose in the k-th scan's frame.
std::vector<std::pair<size_t, Pose2D>> localMap(const TrackRecords& records, size_t k, double reach) {
  const Pose2D centre_inverse = records[k].second.inverse();
  std::vector<std::pair<size_t, Pose2D>> out{{records[k].first, Pose2D{}}};
  for (int step : {-1, 1}) {
    double path = 0;
    for (size_t m = k; step < 0 ? m > 0 : m + 1 < records.size();) {
      const size_t next = step < 0 ? m - 1 : m + 1;
      path += std::hypot(records[next].second.x - records[m].second.x, records[next].second.y - records[m].second.y);
      if (path > reach) break;
      out.emplace_back(records[next].first, centre_inverse.compose(records[next].second));
      m = next;
    }
  }
  return out;
}

// The median of `frames` (heading, and where they put the point c), and their spread about it.
ScanFixedFrame medianFrame(const std::vector<Pose2D>& frames, double cx, double cy) {
  std::vector<double> turns, xs, ys;  // headings about the first frame's (no wrap)
  for (const Pose2D& f : frames) {
    double x, y;
    f.apply(cx, cy, x, y);
    turns.push_back(Pose2D::normalizeAngle(f.yaw - frames.front().yaw)), xs.push_back(x), ys.push_back(y);
  }
  ScanFixedFrame out;
  const double yaw = Pose2D::normalizeAngle(frames.front().yaw + median(turns));
  const double px = median(xs), py = median(ys);
  out.truth = {px - (std::cos(yaw) * cx - std::sin(yaw) * cy), py - (std::sin(yaw) * cx + std::cos(yaw) * cy), yaw};
  double sum_m = 0, sum_deg = 0;
  for (size_t k = 0; k < frames.size(); ++k) {
    sum_m += (xs[k] - px) * (xs[k] - px) + (ys[k] - py) * (ys[k] - py);
    const double d = Pose2D::normalizeAngle(frames[k].yaw - yaw) * 180.0 / M_PI;
    sum_deg += d * d;
  }
  out.spread_m = std::sqrt(sum_m / static_cast<double>(frames.size()));
  out.spread_deg = std::sqrt(sum_deg / static_cast<double>(frames.size()));
  out.relations = frames.size();
  return out;
}

}  // namespace

std::optional<ScanFixedFrame> scanFixedPeerFrame(const slam::RobotLog& log, const RobotTrack& n, const RobotTrack& m,
                                                 const ScanFixedParams& params) {
  const TrackRecords records_n = trackRecords(log, n), records_m = trackRecords(log, m);
  const auto candidates = candidatePairs(log, records_n, records_m, params);
  std::vector<Pose2D> frames;  // T_k
  for (const auto& [a, b] : candidates) {
    const Pose2D guess = log.records[records_n[a].first].reference.inverse().compose(log.records[records_m[b].first].reference);
    const auto relation = localMapRelation(log, localMap(records_n, a, params.local_path), localMap(records_m, b, params.local_path),
                                           guess, params.relation);
    if (relation) frames.push_back(records_n[a].second.compose(*relation).compose(records_m[b].second.inverse()));
  }
  if (frames.size() < std::max<size_t>(params.min_relations, 1)) return std::nullopt;
  double cx, cy;
  pathCentre(m, cx, cy);  // where the error is measured
  ScanFixedFrame out = medianFrame(frames, cx, cy);
  out.tried = candidates.size();
  return out;
}

}  // namespace mrslam::bench
