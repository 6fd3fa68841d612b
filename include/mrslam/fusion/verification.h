// Stage 9: verification of the best transform. A merge is accepted only when every check
// passes; otherwise it is REJECTED with the reason, never returned as a guess.
//  - the paper's acceptance index V = agr / (agr + dis) (eq. 20);
//  - the paper's entropy check (eq. 21): fusing the two maps over their overlap must not make
//    the image more random than the maps were on their own (conflicting cells add a third
//    grey level and raise the entropy of the fused image);
//  - our additions, because V is dominated by free space: the share of B's obstacles that
//    meet A's obstacles (wall agreement), enough shared wall to be evidence at all (in metres
//    and as a share of the smaller map's walls: the merge must explain part of a map), and
//    distinctiveness: the score must drop clearly when B is displaced (about a metre in any
//    direction, or turned a few degrees). Two corridors overlay well at many shifts; a pose
//    that is not a clear extremum is not evidence of where B is (cf. the paper's Fig. 10);
//    likewise a distinct alternative pose (another hypothesis) that scores nearly as well;
//  - physical consistency (see_through.h): no free space seen through the other map's
//    walls. It catches overlays of two buildings that agree cell for cell along one wall, e.g.
//    a corridor laid along the outside of another building's hall (test_merge_regressions);
//  - reach (SimilarityIndex::lever): the shared walls fix the heading over their own spread,
//    and a heading error carries to B's walls in proportion to their distance. Two robots' maps
//    disagree in heading by a few tenths of a degree where they meet; a short corridor stub
//    shared with a map that reaches far beyond it places the far walls cells off (8 robots:
//    robot8 <- robot1 accepted 1.23 degrees and 5 cells from the truth, lever 8.0).
#pragma once

#include <string>

#include "mrslam/fusion/similarity_index.h"

namespace mrslam::fusion {

struct VerificationParams {
  double min_acceptance = 0.97;        // V
  double min_wall_agreement = 0.65;    // share of B's obstacles in A's known space on A's obstacles
  double min_shared_wall_m = 8.0;      // agreeing obstacle cells x resolution
  double min_shared_wall_fraction = 0.15;  // agreeing obstacle cells / obstacle cells of the smaller map
  double max_entropy_increase = 0.15;  // bits: H(fused) - mean(H(A), H(B)) over the overlap
  double min_distinctiveness = 0.15;   // 1 - best displaced score / score
  double distinct_shift_m = 1.0;       // displacement used for distinctiveness
  double distinct_turn_deg = 3.0;      // rotation used for distinctiveness
  double max_ambiguity = 0.95;         // best distinct alternative's score / best score
  double ambiguity_weight_factor = 3.0;  // rivals are also compared with the disagreement weight
                                         // this many times w (set-aside finals only so)
  double max_seen_through = 0.5;       // free space behind the other map's walls (see_through.h)
  double max_lever = 6.0;              // B's far walls' reach over the shared walls' spread
};

// What verify() judges beside the counts.
struct PoseFigures {
  double distinctiveness = 1.0;    // 1 - (best score of the displaced poses) / (score of the pose)
  double smaller_map_walls = 0;    // obstacle cells of the map with fewer of them
  double ambiguity = 0;            // the best distinct alternative pose's score over the pose's
  double seen_through = 0;         // SeeThroughCheck's figure for the pose
  double lever = 0;                // SimilarityIndex::lever at the pose
};

struct Verdict {
  bool accepted = false;
  double acceptance = 0;       // V
  double wall_agreement = 0;
  double shared_wall_m = 0;
  double shared_wall_fraction = 0;
  double entropy_increase = 0;
  double distinctiveness = 0;
  double ambiguity = 0;
  double seen_through = 0;     // free space seen through the other map's walls (see_through.h)
  double lever = 0;            // how far B's walls reach beyond the shared ones (SimilarityIndex::lever)
  std::string reason;          // why it was rejected; empty when accepted
  bool no_overlap_found = false;  // rejected for too little shared wall: the pose explains
                                  // nothing, as opposed to a real overlap failing a check
};

// Entropy increase (bits) of the fused image over the overlap, from the counts (eq. 21).
double fusedEntropyIncrease(const SimilarityCounts& counts);

// The verdict on a pose from its counts and figures. Figures left at their defaults pass (used
// when ranking candidates on their counts alone), except smaller_map_walls.
Verdict verify(const SimilarityCounts& counts, double resolution, const PoseFigures& figures,
               const VerificationParams& params);

}  // namespace mrslam::fusion
