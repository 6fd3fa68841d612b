// Stage 8: the similarity index of Birk & Carpin used by the paper, J = agr - dis, and the
// exhaustive search of the best translation in a window around an approximate one.
//
// agr counts cells that are known in both maps and agree (both occupied or both free); dis
// counts cells known in both maps that disagree (occupied in one, free in the other). Cells
// known in only one map are neither: they are simply not overlap (we follow [9] here; the
// paper's wording "known in at least one map" would punish every non-overlapping cell and
// make partial overlaps unmatchable).
//
// Occupancy grids place the same wall one cell apart in two runs, so agreement on obstacles
// has a one-cell tolerance: map B's obstacle cells agree when they land within one cell of
// an obstacle of A, and B's free cells next to B's own obstacles are not counted at all.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "mrslam/fusion/cell_transform.h"

namespace mrslam::fusion {

struct SimilarityCounts {
  double occupied_agree = 0;     // B occupied on (or next to) A occupied
  double occupied_conflict = 0;  // B occupied on A free
  double free_agree = 0;         // B free on A free
  double free_conflict = 0;      // B free on A occupied

  double agr() const { return occupied_agree + free_agree; }
  double dis() const { return occupied_conflict + free_conflict; }
  double J() const { return agr() - dis(); }  // the paper's similarity index
  // Our ranking score: J with disagreements weighted (weight 1 is the paper's J). Free space
  // dominates agr, so with weight 1 a pose that overlays more free space wins even when it
  // puts walls across rooms; measured on the merge benchmark, see config/fusion.yaml.
  double score(double disagreement_weight) const { return agr() - disagreement_weight * dis(); }
  // The paper's acceptance (verification) index V = agr / (agr + dis), in [0, 1].
  double acceptance() const { return agr() + dis() > 0 ? agr() / (agr() + dis()) : 0.0; }
  // Of B's obstacles that fall in A's known space, the share that meets A's obstacles.
  double wallAgreement() const {
    const double n = occupied_agree + occupied_conflict;
    return n > 0 ? occupied_agree / n : 0.0;
  }
};

struct SearchResult {
  CellTransform transform;
  SimilarityCounts counts;
  bool held = false;  // the merger's current transform, tracked (map_fusion.h, alignMaps)
};

class SimilarityIndex {
 public:
  // Both images are ternary (see ternary_image.h) at the same resolution. At most
  // `max_free_points` of B's free cells are used (an even subsample, reweighted), which keeps
  // the cost per evaluation bounded on large maps. Searches maximise score(disagreement_weight).
  SimilarityIndex(const cv::Mat& ternary_a, const cv::Mat& ternary_b, int max_free_points,
                  double disagreement_weight = 1.0);

  SimilarityCounts evaluate(const CellTransform& transform) const;

  // How far B's obstacles reach beyond the ones that meet A's at `transform` (those counted in
  // occupied_agree): the 90th percentile of their distances from the shared obstacles' centre
  // over the shared obstacles' radius of gyration (infinity with fewer than two shared). A
  // heading fixed by the shared walls to a cell over their spread puts B's far walls about
  // this many cells off.
  double lever(const CellTransform& transform) const;

  // Centre of B's obstacles (cell coordinates of B), the pivot of rotation steps.
  const cv::Point2d& obstacleCentre() const { return center_b_; }

  // Exhaustive search over integer translations within `radius` cells of transform.t, and
  // rotations transform.theta + k * rotation_step for |k| <= rotation_steps (turning B about
  // the centre of its obstacles, so a small turn does not sweep far cells away).
  SearchResult search(const CellTransform& transform, int radius, double rotation_step,
                      int rotation_steps) const;

 private:
  enum LookupClass : uint8_t { kUnknown = 0, kFree = 1, kOccupied = 2, kNearOccupied = 3 };
  cv::Mat lookup_a_;  // LookupClass per cell of A
  std::vector<cv::Point2f> occupied_b_, free_b_;
  double free_weight_ = 1.0;
  double disagreement_weight_ = 1.0;
  cv::Point2d center_b_;  // centre of B's obstacles, the pivot of rotation steps

  void accumulate(const std::vector<cv::Point2f>& points, const CellTransform& transform,
                  bool occupied, int radius, std::vector<SimilarityCounts>& per_offset) const;
};

}  // namespace mrslam::fusion
