#include "mrslam/fusion/map_fusion.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <tuple>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "mrslam/fusion/chamfer_polish.h"
#include "mrslam/fusion/correlation_search.h"
#include "mrslam/fusion/radon.h"
#include "mrslam/fusion/see_through.h"
#include "mrslam/fusion/similarity_index.h"
#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {
namespace {

constexpr double kDeg = M_PI / 180.0;
// Down the pyramid, a survivor scoring under this share of the best stops being refined.
constexpr double kKeepShareOfBest = 0.5;
// The chamfer polish is kept unless the similarity score drops below this share (see polish()).
constexpr double kPolishKeepsScore = 0.9;

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

// 1 - (best score among poses displaced by about a metre or turned a few degrees) / score.
double distinctiveness(const SimilarityIndex& index, const SearchResult& found, double resolution,
                       const FusionParams& params) {
  const double w = params.disagreement_weight;
  const double score = found.counts.score(w);
  if (!(score > 0)) return 0.0;
  const double shift = params.verification.distinct_shift_m / resolution;
  const double turn = params.verification.distinct_turn_deg * kDeg;
  double worst_ratio = -1e300;
  for (int k = 0; k < 8; ++k) {
    const double a = k * M_PI / 4;
    const CellTransform moved{found.transform.theta, found.transform.t + shift * cv::Point2d(std::cos(a), std::sin(a))};
    worst_ratio = std::max(worst_ratio, index.evaluate(moved).score(w) / score);
  }
  for (double sign : {-1.0, 1.0}) {
    const CellTransform turned_pose = turned(found.transform, sign * turn, index.obstacleCentre());
    worst_ratio = std::max(worst_ratio, index.evaluate(turned_pose).score(w) / score);
  }
  return 1.0 - worst_ratio;
}

}  // namespace

Pose2D poseFromCells(const OccupancyGrid& a, const OccupancyGrid& b, const CellTransform& cells) {
  const Pose2D metric{a.resolution * cells.t.x, a.resolution * cells.t.y, Pose2D::normalizeAngle(cells.theta)};
  return a.origin.compose(metric).compose(b.origin.inverse());
}

CellTransform cellsFromPose(const OccupancyGrid& a, const OccupancyGrid& b, const Pose2D& pose) {
  const Pose2D metric = a.origin.inverse().compose(pose).compose(b.origin);
  return {metric.yaw, {metric.x / a.resolution, metric.y / a.resolution}};
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

namespace {

// Times the stages of one search into FusionResult::stage_ms.
class StageClock {
 public:
  explicit StageClock(FusionResult& result) : result_(result) {}
  void lap(const char* name) {
    const auto now = std::chrono::steady_clock::now();
    result_.stage_ms.emplace_back(name, std::chrono::duration<double, std::milli>(now - last_).count());
    last_ = now;
  }
  double totalMs() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  FusionResult& result_;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point last_ = start_;
};

// Both maps as ternary images at A's resolution, their pyramids and the levels each step uses.
struct Images {
  cv::Mat a, b;                        // full resolution (B resampled to A's cells)
  std::vector<cv::Mat> pyr_a, pyr_b;   // level l is 2^l times coarser
  int coarse = 0;                      // where hypotheses are scored
  int fourier = 0;                     // where the Fourier translation search runs (>= coarse)
  int spectrum = 0;                    // where the rotation spectra are taken (<= coarse)
};

Images prepareImages(const OccupancyGrid& a, const OccupancyGrid& b, const FusionParams& params) {
  Images im;
  im.a = toTernary(a, params.occupied_threshold, params.free_threshold);
  im.b = toTernary(b, params.occupied_threshold, params.free_threshold);
  const double ratio = b.resolution / a.resolution;
  if (std::abs(ratio - 1.0) > 1e-6) {
    // Resample B to A's resolution; B's cell coordinates then count A-sized cells.
    cv::resize(im.b, im.b, cv::Size(), ratio, ratio, cv::INTER_NEAREST);
  }
  im.coarse = levelFor(im.a, im.b, params.coarse_max_cells);
  im.fourier = std::max(im.coarse, levelFor(im.a, im.b, params.fourier_max_cells));
  // Rotation spectra want angular detail: the finest level within spectrum_max_cells.
  im.spectrum = std::min(im.coarse, levelFor(im.a, im.b, params.spectrum_max_cells));
  im.pyr_a = pyramid(im.a, im.fourier + 1);
  im.pyr_b = pyramid(im.b, im.fourier + 1);
  return im;
}

// A pose hypothesis on the coarse level with the window its coarse search covers.
struct Hypothesis {
  CellTransform pose;
  int radius;          // translation window (coarse cells)
  int rotation_steps;  // rotation steps either way
};

// Our global search: rotation candidates from the Radon spectra, then for each the best
// translations by Fourier correlation (a small window search follows on the coarse level).
void addSpectrumHypotheses(const Images& im, const FusionParams& params, std::vector<Hypothesis>& out,
                           StageClock& clock) {
  const std::vector<double> alphas =
      globalRotationCandidates(occupiedPoints(im.pyr_a[im.spectrum]), occupiedPoints(im.pyr_b[im.spectrum]),
                               params.spectrum_step_deg * kDeg, params.rotation_candidates);
  clock.lap("spectra");
  const CorrelationSearch correlation(im.pyr_a[im.fourier], im.pyr_b[im.fourier], params.coarse_disagreement_weight);
  const double fourier_to_coarse = std::pow(2.0, im.fourier - im.coarse);
  for (double alpha : alphas)
    for (const CellTransform& h : correlation.candidates(alpha, params.translation_peaks, 2))
      out.push_back({h.scaled(1.0 / fourier_to_coarse), params.coarse_search_radius, params.coarse_rotation_steps});
  clock.lap("fourier");
}

// Paper stages 1-6: matched random segments; each pair's pose gets the paper's window and a
// rotation step either way (its angle is a line fit).
void addSegmentHypotheses(const Images& im, const FusionParams& params, std::vector<Hypothesis>& out) {
  if (!params.use_segments) return;
  const int level = std::min(im.coarse, levelFor(im.a, im.b, params.segment_max_cells));
  std::mt19937 rng(params.seed);
  const SegmentFeatures fa = extractSegments(im.pyr_a[level], params.segments, rng);
  const SegmentFeatures fb = extractSegments(im.pyr_b[level], params.segments, rng);
  const double to_coarse = std::pow(2.0, im.coarse - level);
  const int radius = std::max(1, static_cast<int>(std::ceil(params.segment_search_radius / to_coarse)));
  for (const CellTransform& h : segmentHypotheses(fa, fb, params.segments)) out.push_back({h.scaled(to_coarse), radius, 1});
}

// Scores every hypothesis in its window on the coarse level and keeps the best few distinct ones.
std::vector<CellTransform> bestCoarsePoses(const std::vector<Hypothesis>& hypotheses, const SimilarityIndex& index,
                                           const FusionParams& params) {
  const double step = params.coarse_rotation_step_deg * kDeg, w = params.coarse_disagreement_weight;
  std::vector<SearchResult> scored;
  for (const Hypothesis& h : hypotheses) scored.push_back(index.search(h.pose, h.radius, step, h.rotation_steps));
  std::sort(scored.begin(), scored.end(),
            [w](const SearchResult& x, const SearchResult& y) { return x.counts.score(w) > y.counts.score(w); });
  std::vector<CellTransform> survivors;
  for (const SearchResult& s : scored) {
    if (static_cast<int>(survivors.size()) >= params.refined_hypotheses) break;
    const bool duplicate = std::any_of(survivors.begin(), survivors.end(), [&](const CellTransform& t) {
      return sameHypothesis(t, s.transform, 2.0, 2 * step);
    });
    if (!duplicate) survivors.push_back(s.transform);
  }
  return survivors;
}

// Stage 7, once per survivor on the coarse level: Radon rotation tuning, kept only where the
// similarity index agrees it is better (the pyramid and the polish refine further).
void tuneRotations(const Images& im, const SimilarityIndex& coarse_index, const FusionParams& params,
                   std::vector<CellTransform>& survivors) {
  const double w = params.coarse_disagreement_weight;
  const RadonTuner radon(occupiedPoints(im.pyr_a[im.coarse]), params.radon_window_deg * kDeg,
                         params.radon_step_deg * kDeg, params.radon_peaks);
  const std::vector<cv::Point2f> points_b = occupiedPoints(im.pyr_b[im.coarse]);
  cv::Point2d pivot;
  for (const auto& p : points_b) pivot += cv::Point2d(p);
  pivot /= static_cast<double>(std::max<size_t>(1, points_b.size()));
  std::vector<cv::Point2f> rotated(points_b.size());
  for (CellTransform& h : survivors) {
    const CellTransform rotation{h.theta, {0, 0}};
    for (size_t k = 0; k < points_b.size(); ++k) rotated[k] = cv::Point2f(rotation.apply(points_b[k]));
    const CellTransform tuned = turned(h, radon.tune(rotated), pivot);
    if (coarse_index.search(tuned, 1, 0, 0).counts.score(w) > coarse_index.search(h, 1, 0, 0).counts.score(w)) h = tuned;
  }
}

// Stage 8 down the pyramid: each survivor is searched again on every finer level (translation
// window refine_radius, rotation step halving per level). Returns the finest level's index
// (null when the coarse level is already full resolution).
std::unique_ptr<SimilarityIndex> refineDownThePyramid(const Images& im, const FusionParams& params,
                                                      std::vector<SearchResult>& finals) {
  const double w = params.disagreement_weight;
  std::unique_ptr<SimilarityIndex> finest;
  for (int level = im.coarse - 1; level >= 0; --level) {
    finest = std::make_unique<SimilarityIndex>(im.pyr_a[level], im.pyr_b[level], params.max_free_points, w);
    const double step = params.coarse_rotation_step_deg * kDeg / std::pow(2.0, im.coarse - level);
    for (SearchResult& f : finals) f = finest->search(f.transform.scaled(0.5), params.refine_radius, step, 1);
    // A survivor scoring under half of the best, with the weights the ambiguity check compares
    // at (w and k w), can neither win nor make the pose ambiguous (max_ambiguity is far above
    // that): stop spending finer levels on it. At w alone a small clean overlay at the right pose
    // fell here behind a twin twice its size that k w rejects (Intel's mirrored arcs).
    const double kw = params.verification.ambiguity_weight_factor * w;
    double top = -1e300, top_kw = -1e300;
    for (const SearchResult& f : finals) {
      top = std::max(top, f.counts.score(w));
      top_kw = std::max(top_kw, f.counts.score(kw));
    }
    auto behind = [&](const SearchResult& f) {
      return top > 0 && f.counts.score(w) < kKeepShareOfBest * top &&
             (top_kw <= 0 || f.counts.score(kw) < kKeepShareOfBest * top_kw);
    };
    finals.erase(std::remove_if(finals.begin(), finals.end(), behind), finals.end());
  }
  return finest;
}

// Polish every survivor before choosing: the pyramid ends with quarter-degree rotation
// steps (a cell or more at 30 m), enough for a symmetric impostor (ACES turned by 180
// degrees) to outscore the slightly misaligned truth. The polish is kept unless the
// similarity index drops by a tenth (a diverged polish): it reads a subsample of B's free
// cells, whose aliasing with one-cell walls moves a score by 1-2 % from one pose to the next,
// so a tighter guard (we had 2 %) threw away polishes that moved a pose 2 cells closer to
// the truth (scripts/bench_merge, an ACES window pair of seed 99).
void polish(const Images& im, const SimilarityIndex& full, const FusionParams& params, std::vector<SearchResult>& finals) {
  const ChamferPolish chamfer(im.a, im.b, params.chamfer_truncation);
  for (SearchResult& f : finals) {
    const CellTransform polished = chamfer.polish(f.transform);
    const SimilarityCounts counts = full.evaluate(polished);
    if (counts.score(params.disagreement_weight) >= kPolishKeepsScore * f.counts.score(params.disagreement_weight))
      f.transform = polished, f.counts = counts;
  }
}

// The best-scoring final whose own counts pass the checks (V, wall agreement, shared wall,
// entropy) moves to the front; a final that fails them contradicts the maps and is set aside as
// the answer. Returns how many were set aside (all of them when none is plausible: the best one
// then stays in front and is reported with its reason).
template <typename Plausible>
int bringBestPlausibleToFront(std::vector<SearchResult>& finals, double w, const Plausible& plausible) {
  std::sort(finals.begin(), finals.end(),
            [w](const SearchResult& x, const SearchResult& y) { return x.counts.score(w) > y.counts.score(w); });
  const auto first_plausible = std::find_if(finals.begin(), finals.end(), plausible);
  if (first_plausible == finals.end()) return 0;
  std::rotate(finals.begin(), first_plausible, first_plausible + 1);
  return static_cast<int>(first_plausible - finals.begin());
}

// The best distinct plausible alternative: a pose elsewhere that explains the maps nearly as
// well means we cannot tell where B is (symmetric buildings, repeated rooms). The comparison is
// made with the disagreement weight w and again with k w (ambiguity_weight_factor): a choice
// that flips when conflicts count k times is not a choice we can stand behind (a small clean
// overlap against a larger one with a few percent of conflicts, e.g. ACES and its half-turn
// twin, or Intel's two mirrored arcs). A set-aside final is a rival only with k w: a twin that
// loses on its own counts yet still outscores the answer when conflicts count k times is one we
// cannot rule out with confidence either.
template <typename Plausible>
double ambiguity(const std::vector<SearchResult>& finals, double resolution, const FusionParams& params,
                 const Plausible& plausible) {
  const SearchResult& best = finals.front();
  const double w = params.disagreement_weight;
  double worst = best.counts.score(w) > 0 ? 0.0 : 1.0;
  const double distinct_cells = params.verification.distinct_shift_m / resolution;
  for (const SearchResult& f : finals) {
    if (&f == &best ||
        sameHypothesis(f.transform, best.transform, distinct_cells, params.verification.distinct_turn_deg * kDeg))
      continue;
    const bool contradicts_maps = !plausible(f);
    for (const double weight : {w, params.verification.ambiguity_weight_factor * w}) {
      if (contradicts_maps && weight == w) continue;
      const double best_score = best.counts.score(weight);
      worst = std::max(worst, best_score > 0 ? f.counts.score(weight) / best_score : 1.0);
    }
  }
  return worst;
}

// The held pose as one more final: searched in a window of the finest level's size, so that it
// follows maps that grew a little since it was accepted, then treated like the search's finals.
void addHeldPose(const Images& im, const SimilarityIndex& full, const FusionParams& params, const CellTransform& held,
                 std::vector<SearchResult>& finals) {
  const double step = params.coarse_rotation_step_deg * kDeg / std::pow(2.0, im.coarse);
  finals.push_back(full.search(held, params.refine_radius, step, 1));
  finals.back().held = true;
}

FusionResult searchAndVerify(const OccupancyGrid& a, const OccupancyGrid& b, const FusionParams& params,
                             const std::optional<Pose2D>& held) {
  FusionResult result;
  StageClock clock(result);
  const Images im = prepareImages(a, b, params);
  clock.lap("prepare");

  std::vector<Hypothesis> hypotheses;
  addSpectrumHypotheses(im, params, hypotheses, clock);
  addSegmentHypotheses(im, params, hypotheses);
  clock.lap("segments");
  result.hypotheses = static_cast<int>(hypotheses.size());

  const SimilarityIndex coarse_index(im.pyr_a[im.coarse], im.pyr_b[im.coarse], params.max_free_points,
                                     params.coarse_disagreement_weight);
  std::vector<CellTransform> survivors = bestCoarsePoses(hypotheses, coarse_index, params);
  clock.lap("coarse");
  tuneRotations(im, coarse_index, params, survivors);
  clock.lap("radon");

  std::vector<SearchResult> finals(survivors.size());
  for (size_t i = 0; i < survivors.size(); ++i) finals[i].transform = survivors[i];
  const std::unique_ptr<SimilarityIndex> finest = refineDownThePyramid(im, params, finals);
  clock.lap("pyramid");
  // Maps that fit the coarse level have no finer one: their windows (the held pose's too) are
  // then searched with the coarse weight; the choice between finals uses the full weight.
  const SimilarityIndex& full = finest ? *finest : coarse_index;
  if (!finest)
    for (SearchResult& f : finals) f.counts = full.evaluate(f.transform);
  if (held) addHeldPose(im, full, params, cellsFromPose(a, b, *held), finals);
  if (params.chamfer_polish && finest) polish(im, full, params, finals);

  const double smaller_walls =
      std::min(countCells(im.a, kOccupiedCell), countCells(im.b, kOccupiedCell));
  // A transform the merger holds was accepted while it explained enough of the smaller map; as
  // the robots map apart that share falls with the overlap unchanged (a relay of the 8-robot
  // multi-host runs: shared wall 9.3 -> 10.2 m, share 0.15 -> 0.13, revoked). What revokes a held
  // transform is evidence against it, not a shrinking share.
  VerificationParams held_checks = params.verification;
  held_checks.min_shared_wall_fraction = 0;
  auto checks = [&](const SearchResult& f) -> const VerificationParams& {
    return f.held ? held_checks : params.verification;
  };
  auto plausible = [&](const SearchResult& f) {
    PoseFigures counts_only;
    counts_only.smaller_map_walls = smaller_walls;
    return verify(f.counts, a.resolution, counts_only, checks(f)).accepted;
  };
  result.set_aside = bringBestPlausibleToFront(finals, params.disagreement_weight, plausible);
  if (finals.empty()) {
    result.verdict.reason = "no hypothesis found";
  } else {
    const SearchResult& best = finals.front();
    const double rivals = ambiguity(finals, a.resolution, params, plausible);
    clock.lap("polish");
    result.cells = best.transform;
    PoseFigures figures;
    figures.distinctiveness = distinctiveness(full, best, a.resolution, params);
    figures.smaller_map_walls = smaller_walls;
    figures.ambiguity = rivals;
    figures.seen_through = SeeThroughCheck(im.a, im.b).seenThrough(best.transform);
    figures.lever = full.lever(best.transform);
    result.verdict = verify(best.counts, a.resolution, figures, checks(best));
    result.accepted = result.verdict.accepted;
    result.pose = poseFromCells(a, b, result.cells);
    clock.lap("verify");
  }
  result.time_ms = clock.totalMs();
  return result;
}

}  // namespace

std::string peerMapProblem(const OccupancyGrid& b, double own_resolution, const FusionParams& params) {
  const std::string why = checkFusable(b, params);
  if (!why.empty()) return why;
  if (own_resolution == 0.0) return "";
  const double ratio = b.resolution / own_resolution;
  if (!(ratio <= params.max_resolution_ratio && ratio >= 1.0 / params.max_resolution_ratio))
    return "resolutions " + std::to_string(own_resolution) + " and " + std::to_string(b.resolution) +
           " differ too much to resample (more than " + std::to_string(params.max_resolution_ratio) + " times)";
  return "";
}

std::string fusionInputProblem(const OccupancyGrid& a, const OccupancyGrid& b, const FusionParams& params) {
  const std::string why = checkFusable(a, params);
  if (!why.empty()) return "map A: " + why;
  const std::string why_b = peerMapProblem(b, a.resolution, params);
  return why_b.empty() || why_b.rfind("resolutions", 0) == 0 ? why_b : "map B: " + why_b;
}

FusionResult alignMaps(const OccupancyGrid& a, const OccupancyGrid& b, const FusionParams& params,
                       const std::optional<Pose2D>& held) {
  const std::string problem = fusionInputProblem(a, b, params);
  if (!problem.empty()) throw std::invalid_argument(problem);
  const double ratio = b.resolution / a.resolution;
  FusionResult result = searchAndVerify(a, b, params, held);
  if (result.accepted || !result.verdict.no_overlap_found || params.retry_finer < 1) return result;
  // Nothing found: once more with finer coarse and Fourier levels and more rotation candidates
  // (about 4x the time), if the maps are large enough for that to change anything.
  FusionParams finer = params;
  finer.coarse_max_cells = params.coarse_max_cells << params.retry_finer;
  finer.fourier_max_cells = params.fourier_max_cells << params.retry_finer;
  finer.rotation_candidates = std::max(params.rotation_candidates, params.retry_rotation_candidates);
  const int longest = std::max({a.width, a.height, static_cast<int>(std::lround(b.width * ratio)),
                                static_cast<int>(std::lround(b.height * ratio))});
  if (longest <= params.coarse_max_cells) return result;  // already searched at full resolution
  FusionResult retry = searchAndVerify(a, b, finer, held);
  retry.time_ms += result.time_ms;
  retry.hypotheses += result.hypotheses;
  double first_ms = 0;
  for (const auto& [stage, ms] : result.stage_ms) first_ms += ms;
  retry.stage_ms.insert(retry.stage_ms.begin(), {"first search", first_ms});
  return retry;
}

}  // namespace mrslam::fusion
