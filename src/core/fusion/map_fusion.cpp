#include "mrslam/fusion/map_fusion.h"

#include <algorithm>
#include <chrono>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "mrslam/fusion/correlation_search.h"
#include "mrslam/fusion/radon.h"
#include "mrslam/fusion/similarity_index.h"
#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {
namespace {

constexpr double kDeg = M_PI / 180.0;

std::vector<cv::Mat> pyramid(const cv::Mat& level0, int levels) {
  std::vector<cv::Mat> out{level0};
  for (int l = 1; l < levels; ++l) out.push_back(downsampleTernary(out.back()));
  return out;
}

// Smallest level at which both maps fit in max_cells (but at least one level exists).
int levelFor(const cv::Mat& a, const cv::Mat& b, int max_cells) {
  int side = std::max({a.rows, a.cols, b.rows, b.cols}), level = 0;
  while (side > max_cells) side = (side + 1) / 2, ++level;
  return level;
}

bool sameHypothesis(const CellTransform& x, const CellTransform& y, double cells, double angle) {
  return cv::norm(x.t - y.t) <= cells &&
         std::abs(std::remainder(x.theta - y.theta, 2 * M_PI)) <= angle;
}

// Turns B by delta about `pivot` (a point of B) keeping the pivot where it was.
CellTransform turned(const CellTransform& h, double delta, const cv::Point2d& pivot) {
  CellTransform out{h.theta + delta, h.t};
  out.t += h.apply(pivot) - out.apply(pivot);
  return out;
}

}  // namespace

Pose2D poseFromCells(const OccupancyGrid& a, const OccupancyGrid& b, const CellTransform& cells) {
  const Pose2D metric{a.resolution * cells.t.x, a.resolution * cells.t.y, Pose2D::normalizeAngle(cells.theta)};
  return a.origin.compose(metric).compose(b.origin.inverse());
}

std::string checkFusable(const OccupancyGrid& grid, const FusionParams& params) {
  std::string why = validateGrid(grid);
  if (!why.empty()) return why;
  size_t known = 0, occupied = 0;
  for (int8_t v : grid.data) {
    if (v >= 0) ++known;
    if (v >= params.occupied_threshold) ++occupied;
  }
  if (known == 0) return "map has no known cells (all unknown)";
  if (occupied < 10) return "map has no obstacle edges to match (" + std::to_string(occupied) + " obstacle cells)";
  return "";
}

FusionResult alignMaps(const OccupancyGrid& a, const OccupancyGrid& b, const FusionParams& params) {
  const auto start = std::chrono::steady_clock::now();
  for (const OccupancyGrid* g : {&a, &b}) {
    const std::string why = checkFusable(*g, params);
    if (!why.empty()) throw std::invalid_argument(std::string(g == &a ? "map A: " : "map B: ") + why);
  }
  const double ratio = b.resolution / a.resolution;
  if (ratio > params.max_resolution_ratio || ratio < 1.0 / params.max_resolution_ratio)
    throw std::invalid_argument("resolutions " + std::to_string(a.resolution) + " and " +
                                std::to_string(b.resolution) + " differ too much to resample");

  const cv::Mat ternary_a = toTernary(a, params.occupied_threshold, params.free_threshold);
  cv::Mat ternary_b = toTernary(b, params.occupied_threshold, params.free_threshold);
  if (std::abs(ratio - 1.0) > 1e-6) {
    // Resample B to A's resolution; B's cell coordinates then count A-sized cells.
    cv::resize(ternary_b, ternary_b, cv::Size(), ratio, ratio, cv::INTER_NEAREST);
  }

  const int coarse = levelFor(ternary_a, ternary_b, params.coarse_max_cells);
  const int spectrum_level = std::min(coarse, levelFor(ternary_a, ternary_b, params.spectrum_max_cells));
  const std::vector<cv::Mat> pyr_a = pyramid(ternary_a, coarse + 1), pyr_b = pyramid(ternary_b, coarse + 1);
  const double coarse_scale = std::pow(2.0, coarse);

  // Hypotheses on the coarse level, each with the radius of its similarity search.
  std::vector<std::pair<CellTransform, int>> hypotheses;
  const std::vector<cv::Point2f> spectrum_a = occupiedPoints(pyr_a[spectrum_level]);
  const std::vector<cv::Point2f> spectrum_b = occupiedPoints(pyr_b[spectrum_level]);
  const CorrelationSearch correlation(pyr_a[coarse], pyr_b[coarse], params.conflict_penalty);
  for (double alpha : globalRotationCandidates(spectrum_a, spectrum_b, params.spectrum_step_deg * kDeg,
                                               params.rotation_candidates))
    for (double theta : {alpha, alpha + M_PI})
      for (const CellTransform& h : correlation.candidates(theta, params.translation_peaks, 3))
        hypotheses.emplace_back(h, params.coarse_search_radius);
  if (params.use_segments) {
    const int level = std::min(coarse, levelFor(ternary_a, ternary_b, params.segment_max_cells));
    std::mt19937 rng(params.seed);
    const SegmentFeatures fa = extractSegments(pyr_a[level], params.segments, rng);
    const SegmentFeatures fb = extractSegments(pyr_b[level], params.segments, rng);
    const double to_coarse = std::pow(2.0, coarse - level);
    const int radius = std::max(1, static_cast<int>(std::ceil(params.segment_search_radius / to_coarse)));
    for (const CellTransform& h : segmentHypotheses(fa, fb, params.segments))
      hypotheses.emplace_back(h.scaled(to_coarse), radius);
  }

  FusionResult result;
  result.hypotheses = static_cast<int>(hypotheses.size());
  const SimilarityIndex coarse_index(pyr_a[coarse], pyr_b[coarse], params.max_free_points);
  const double coarse_step = params.coarse_rotation_step_deg * kDeg;
  std::vector<SearchResult> scored;
  for (const auto& [h, radius] : hypotheses) scored.push_back(coarse_index.search(h, radius, coarse_step, 1));
  std::sort(scored.begin(), scored.end(),
            [](const SearchResult& x, const SearchResult& y) { return x.counts.J() > y.counts.J(); });
  std::vector<CellTransform> survivors;
  for (const SearchResult& s : scored) {
    if (static_cast<int>(survivors.size()) >= params.refined_hypotheses) break;
    const bool duplicate = std::any_of(survivors.begin(), survivors.end(), [&](const CellTransform& t) {
      return sameHypothesis(t, s.transform, 2.0, 2 * coarse_step);
    });
    if (!duplicate) survivors.push_back(s.transform);
  }

  // Tune the survivors level by level down to full resolution.
  std::vector<SearchResult> finals(survivors.size());
  for (size_t i = 0; i < survivors.size(); ++i) finals[i].transform = survivors[i];
  for (int level = coarse - 1; level >= 0; --level) {
    const SimilarityIndex index(pyr_a[level], pyr_b[level], params.max_free_points);
    const double step = coarse_step / std::pow(2.0, coarse - level);
    std::vector<cv::Point2f> points_a, points_b;
    cv::Point2d pivot;
    if (level == spectrum_level) {
      points_a = occupiedPoints(pyr_a[level]);
      points_b = occupiedPoints(pyr_b[level]);
      for (const auto& p : points_b) pivot += cv::Point2d(p);
      pivot /= static_cast<double>(std::max<size_t>(1, points_b.size()));
    }
    for (SearchResult& f : finals) {
      CellTransform h = f.transform.scaled(0.5);
      if (level == spectrum_level) {
        // Stage 7: Radon tuning; kept only if the similarity index agrees it is better.
        std::vector<cv::Point2f> rotated(points_b.size());
        const CellTransform rotation{h.theta, {0, 0}};
        for (size_t k = 0; k < points_b.size(); ++k) rotated[k] = cv::Point2f(rotation.apply(points_b[k]));
        const double delta = radonRotationTuning(points_a, rotated, params.radon_window_deg * kDeg,
                                                 params.radon_step_deg * kDeg);
        const CellTransform tuned = turned(h, delta, pivot);
        if (index.search(tuned, params.refine_radius, 0, 0).counts.J() >
            index.search(h, params.refine_radius, 0, 0).counts.J())
          h = tuned;
      }
      f = index.search(h, params.refine_radius, step, 1);
    }
  }
  if (coarse == 0) {
    for (SearchResult& f : finals) f.counts = coarse_index.evaluate(f.transform);
  }

  const auto best = std::max_element(finals.begin(), finals.end(), [](const SearchResult& x, const SearchResult& y) {
    return x.counts.J() < y.counts.J();
  });
  if (best == finals.end()) {
    result.verdict.reason = "no hypothesis found";
  } else {
    result.cells = best->transform;
    result.verdict = verify(best->counts, a.resolution, params.verification);
    result.accepted = result.verdict.accepted;
    result.pose = poseFromCells(a, b, result.cells);
  }
  result.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace mrslam::fusion
