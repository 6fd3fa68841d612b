#include "mrslam/fusion/verification.h"

#include <cmath>
#include <initializer_list>
#include <sstream>

namespace mrslam::fusion {
namespace {

double entropy(std::initializer_list<double> counts) {
  double total = 0, h = 0;
  for (double c : counts) total += c;
  if (total <= 0) return 0;
  for (double c : counts)
    if (c > 0) h -= (c / total) * std::log2(c / total);
  return h;
}

}  // namespace

double fusedEntropyIncrease(const SimilarityCounts& k) {
  // Over the overlap each map shows free or occupied cells; the fused image shows agreeing
  // free, agreeing occupied, and conflicting cells (a third grey level).
  const double h_a = entropy({k.free_agree + k.occupied_conflict, k.occupied_agree + k.free_conflict});
  const double h_b = entropy({k.free_agree + k.free_conflict, k.occupied_agree + k.occupied_conflict});
  const double h_fused = entropy({k.free_agree, k.occupied_agree, k.dis()});
  return h_fused - 0.5 * (h_a + h_b);
}

Verdict verify(const SimilarityCounts& counts, double resolution, const PoseFigures& f, const VerificationParams& p) {
  Verdict v;
  v.seen_through = f.seen_through;
  v.ambiguity = f.ambiguity;
  v.lever = f.lever;
  v.shared_wall_fraction = f.smaller_map_walls > 0 ? counts.occupied_agree / f.smaller_map_walls : 0.0;
  v.distinctiveness = f.distinctiveness;
  v.acceptance = counts.acceptance();
  v.wall_agreement = counts.wallAgreement();
  v.shared_wall_m = counts.occupied_agree * resolution;
  v.entropy_increase = fusedEntropyIncrease(counts);
  std::ostringstream why;
  why.precision(3);
  v.no_overlap_found = v.shared_wall_m < p.min_shared_wall_m || v.shared_wall_fraction < p.min_shared_wall_fraction;
  if (v.shared_wall_m < p.min_shared_wall_m)
    why << "too little shared wall (" << v.shared_wall_m << " m < " << p.min_shared_wall_m << " m)";
  else if (v.shared_wall_fraction < p.min_shared_wall_fraction)
    why << "too small a share of the smaller map's walls shared (" << v.shared_wall_fraction << " < "
        << p.min_shared_wall_fraction << ")";
  else if (v.acceptance < p.min_acceptance)
    why << "acceptance index V " << v.acceptance << " < " << p.min_acceptance;
  else if (v.wall_agreement < p.min_wall_agreement)
    why << "wall agreement " << v.wall_agreement << " < " << p.min_wall_agreement;
  else if (v.entropy_increase > p.max_entropy_increase)
    why << "entropy increase " << v.entropy_increase << " bits > " << p.max_entropy_increase;
  else if (v.seen_through > p.max_seen_through)
    why << "free space seen through the other map's walls (" << v.seen_through << " > " << p.max_seen_through << ")";
  else if (!(v.lever <= p.max_lever))
    why << "the shared walls fix too little of the map: its walls reach " << v.lever << " times as far as the shared "
        << "walls spread (> " << p.max_lever << ")";
  else if (v.ambiguity > p.max_ambiguity)
    why << "ambiguous: another pose scores " << v.ambiguity << " of the best (> " << p.max_ambiguity << ")";
  else if (v.distinctiveness < p.min_distinctiveness)
    why << "ambiguous: displaced poses score nearly as well (distinctiveness " << v.distinctiveness
        << " < " << p.min_distinctiveness << ")";
  v.reason = why.str();
  v.accepted = v.reason.empty();
  return v;
}

}  // namespace mrslam::fusion
