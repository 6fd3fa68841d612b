#include "mrslam/fusion/peer_quarantine.h"

namespace mrslam::fusion {

bool PeerQuarantine::isQuarantined(const std::string& peer, double now) const {
  const auto it = records_.find(peer);
  return it != records_.end() && now < it->second.until;
}

bool PeerQuarantine::reportBad(const std::string& peer, double now) {
  Record& r = records_[peer];
  if (now < r.until) return false;  // already quarantined
  if (++r.bad_in_a_row < params_.bad_maps_in_a_row) return false;
  r.bad_in_a_row = 0;  // heard again from scratch once the period ends
  r.until = now + params_.period_s;
  return true;
}

void PeerQuarantine::reportGood(const std::string& peer) {
  const auto it = records_.find(peer);
  if (it != records_.end()) it->second.bad_in_a_row = 0;
}

std::vector<std::string> PeerQuarantine::quarantined(double now) const {
  std::vector<std::string> out;
  for (const auto& [peer, r] : records_)
    if (now < r.until) out.push_back(peer);
  return out;
}

}  // namespace mrslam::fusion
