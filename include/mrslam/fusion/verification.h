// Stage 9: verification of the best transform. A merge is accepted only when every check
// passes; otherwise it is REJECTED with the reason, never returned as a guess.
//  - the paper's acceptance index V = agr / (agr + dis) (eq. 20);
//  - the paper's entropy check (eq. 21): fusing the two maps over their overlap must not make
//    the image more random than the maps were on their own (conflicting cells add a third
//    grey level and raise the entropy of the fused image);
//  - our additions, because V is dominated by free space: the share of B's obstacles that
//    meet A's obstacles (wall agreement), and enough shared wall to be evidence at all.
#pragma once

#include <string>

#include "mrslam/fusion/similarity_index.h"

namespace mrslam::fusion {

struct VerificationParams {
  double min_acceptance = 0.90;        // V
  double min_wall_agreement = 0.60;    // share of B's obstacles in A's known space on A's obstacles
  double min_shared_wall_m = 8.0;      // agreeing obstacle cells x resolution
  double max_entropy_increase = 0.10;  // bits: H(fused) - mean(H(A), H(B)) over the overlap
};

struct Verdict {
  bool accepted = false;
  double acceptance = 0;       // V
  double wall_agreement = 0;
  double shared_wall_m = 0;
  double entropy_increase = 0;
  std::string reason;          // why it was rejected; empty when accepted
};

// Entropy increase (bits) of the fused image over the overlap, from the counts (eq. 21).
double fusedEntropyIncrease(const SimilarityCounts& counts);

Verdict verify(const SimilarityCounts& counts, double resolution, const VerificationParams& params);

}  // namespace mrslam::fusion
