// The map fusion pipeline: finds the pose of map B's frame in map A's frame, or rejects.
//
// Paper stages (Saeedi et al. 2011, Fig. 1) and where they live:
//   1 edge detection ........ ternary_image.h     5 cross-correlation ..... segment.h
//   2 edge smoothing ........ edge_smoothing.h    6 approximate pose ...... approximate_pose.h
//   3 random segment ........ segment.h           7 Radon rotation tuning . radon.h
//   4 segment verification .. segment.h           8 similarity index ...... similarity_index.h
//                                                 9 verification .......... verification.h
// Our extensions, needed for any rotation, any map size and partial overlap (see README):
//   - a coarse global search that adds hypotheses to the paper's segment pairs: rotation
//     candidates from the Radon line-energy spectra of both maps (radon.h), and for each the
//     best translations by Fourier-domain correlation (correlation_search.h);
//   - every hypothesis is scored by the similarity index on a coarse pyramid level, and the
//     best few are tuned level by level down to full resolution (Radon tuning once, then the
//     similarity-index search of translation and a shrinking rotation step at every level);
//   - verification adds wall agreement and a minimum shared wall length to V and entropy.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mrslam/fusion/cell_transform.h"
#include "mrslam/fusion/segment_matching.h"
#include "mrslam/fusion/verification.h"
#include "mrslam/grid.h"

namespace mrslam::fusion {

struct FusionParams {
  int occupied_threshold = 65;  // grid value >= this is an obstacle
  int free_threshold = 25;      // 0 <= grid value <= this is free

  bool use_segments = true;     // the paper's random-segment hypotheses
  SegmentMatchingParams segments;
  int segment_max_cells = 600;  // segments are drawn on the finest pyramid level within this size
  unsigned seed = 1;            // random segments are seeded: runs are reproducible

  int spectrum_max_cells = 800;   // pyramid level used for Radon spectra
  double spectrum_step_deg = 1.0;
  int rotation_candidates = 5;    // spectrum peaks; each is tried at alpha and alpha + 180 deg
  int coarse_max_cells = 256;     // coarse pyramid level where hypotheses are scored
  int fourier_max_cells = 256;    // level of the Fourier translation search (>= coarse level)
  int translation_peaks = 6;      // correlation peaks per rotation

  int coarse_search_radius = 1;   // similarity search around each Fourier hypothesis (coarse cells)
  int segment_search_radius = 10; // the paper's "ten cells" around a segment hypothesis
  double coarse_rotation_step_deg = 1.0;
  int coarse_rotation_steps = 0;  // rotation steps either way when scoring Fourier hypotheses
  int refined_hypotheses = 3;     // best coarse hypotheses tuned down to full resolution
  double radon_window_deg = 2.0;  // Radon tuning searches +- this around the hypothesis
  double radon_step_deg = 0.25;
  int radon_peaks = 4;            // A's strongest line directions used by the tuning
  int refine_radius = 1;          // similarity search per finer level (cells of that level)
  bool chamfer_polish = true;     // sub-cell polish on A's wall distance transform
  double chamfer_truncation = 2.0;  // cells; walls farther apart do not pull
  int max_free_points = 15000;    // free cells of B used per similarity evaluation
  double disagreement_weight = 10.0;  // ranking score agr - w * dis (w = 1: the paper's J)
  double coarse_disagreement_weight = 5.0;  // the same weight where the Fourier search finds and
                                            // the coarse level scores and tunes hypotheses

  int retry_finer = 0;            // a search whose best pose shares too little wall is repeated
                                  // with the coarse and Fourier levels this many levels finer
  int retry_rotation_candidates = 5;  // ...and this many spectrum peaks
  double max_resolution_ratio = 4.0;  // maps whose resolutions differ more are refused
  VerificationParams verification;
};

struct FusionResult {
  bool accepted = false;
  Pose2D pose;           // pose of B's map frame in A's map frame (valid when accepted)
  CellTransform cells;   // the same in A's cells (B resampled to A's resolution)
  Verdict verdict;
  int hypotheses = 0;    // hypotheses scored on the coarse level
  // Final poses that outscored the answer but failed the checks on their own counts (V, wall
  // agreement, shared wall, entropy) and were set aside, e.g. a symmetric building's twin.
  int set_aside = 0;
  double time_ms = 0;
  // Where the time went: preparation, rotation spectra, Fourier search, segments, coarse
  // scoring, pyramid tuning, polish and verification (milliseconds each).
  std::vector<std::pair<std::string, double>> stage_ms;
};

// Pose of B's map frame in A's map frame from a transform in A's cells (B resampled to A's
// resolution): origin_A o (R(theta), resolution_A * t) o origin_B^-1.
Pose2D poseFromCells(const OccupancyGrid& a, const OccupancyGrid& b, const CellTransform& cells);
// The inverse of poseFromCells.
CellTransform cellsFromPose(const OccupancyGrid& a, const OccupancyGrid& b, const Pose2D& pose);

// Why a grid cannot take part in fusion (empty string if it can): invalid structure, no
// known cells, or no obstacle edges.
std::string checkFusable(const OccupancyGrid& grid, const FusionParams& params);

// Why a peer's map B cannot be fused into a map of resolution `own_resolution` (empty string
// if it can): checkFusable, or resolutions further apart than max_resolution_ratio (not
// checked while own_resolution is 0, i.e. unknown). The map-merge nodelet asks this of every
// peer map before it keeps it, so nothing a peer sends can make the fusion throw.
std::string peerMapProblem(const OccupancyGrid& b, double own_resolution, const FusionParams& params);

// Why B cannot be fused into A (empty string if it can): exactly what alignMaps refuses,
// checkFusable on A and peerMapProblem on B.
std::string fusionInputProblem(const OccupancyGrid& a, const OccupancyGrid& b, const FusionParams& params);

// Throws std::invalid_argument when fusionInputProblem is not empty. A rejected merge is not an error: accepted == false and verdict.reason says why.
// When the best pose found shares too little wall to be evidence of anything (verdict
// no_overlap_found), the whole search runs again on levels retry_finer times finer, with
// retry_rotation_candidates rotation candidates (our extension: long corridors can vanish at
// the coarse level); a pose rejected for any other reason (ambiguity, V, entropy) is final.
// The answer is the best-scoring final pose that passes the checks on its own counts; poses
// that fail them are neither the answer nor rivals in the ambiguity check.
// `held`: a pose of B's frame accepted earlier (the merger's current transform). It joins the
// search's finals at full resolution and is ranked and verified like them, so a re-estimate on
// grown maps still confirms it when the coarse search happens to miss it, and never accepts it
// when the grown maps contradict it. One check is not asked of it again: the share of the
// smaller map's walls, which falls as the robots map apart while the overlap stays.
FusionResult alignMaps(const OccupancyGrid& a, const OccupancyGrid& b, const FusionParams& params,
                       const std::optional<Pose2D>& held = std::nullopt);

}  // namespace mrslam::fusion
