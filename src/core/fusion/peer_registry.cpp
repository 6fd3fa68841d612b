#include "mrslam/fusion/peer_registry.h"

#include <algorithm>

namespace mrslam::fusion {

size_t knownCells(const OccupancyGrid& grid) {
  return static_cast<size_t>(std::count_if(grid.data.begin(), grid.data.end(), [](int8_t v) { return v >= 0; }));
}

bool isValidRobotId(const std::string& id) {
  auto letter = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); };
  auto digit = [](char c) { return c >= '0' && c <= '9'; };
  if (id.empty() || id.size() > 64 || !letter(id[0])) return false;
  return std::all_of(id.begin(), id.end(), [&](char c) { return letter(c) || digit(c) || c == '_'; });
}

PeerRegistry::PeerRegistry(std::string self_id, const PeerRegistryParams& params)
    : self_(std::move(self_id)), params_(params) {}

bool PeerRegistry::updatePeer(const std::string& id, std::shared_ptr<const OccupancyGrid> map, uint32_t version,
                              double now) {
  auto [it, inserted] = peers_.try_emplace(id);
  Peer& peer = it->second;
  bool rejoined = inserted;
  if (!inserted && version < peer.version) {  // restarted: a new map frame
    peer = Peer{};
    rejoined = true;
  }
  if (rejoined) {
    peer.id = id;
    peer.first_seen = now;
  }
  peer.map = std::move(map);
  peer.version = version;
  peer.last_seen = now;
  peer.known_cells = knownCells(*peer.map);
  return rejoined;
}

std::optional<std::string> PeerRegistry::nextToEstimate(size_t own_known_cells, double clock) const {
  std::optional<std::string> best, stale;
  double best_growth = 0, oldest = clock;
  for (const auto& [id, peer] : peers_) {
    if (!peer.map || own_known_cells < params_.min_known_cells || peer.known_cells < params_.min_known_cells) continue;
    if (peer.attempts == 0) return id;
    const double peer_growth = peer.known_at_estimate ? static_cast<double>(peer.known_cells) / peer.known_at_estimate - 1 : 1;
    const double own_growth = peer.own_known_at_estimate ? static_cast<double>(own_known_cells) / peer.own_known_at_estimate - 1 : 1;
    const double growth = std::max(peer_growth, own_growth);
    if (growth >= params_.regrow_fraction && growth > best_growth) best = id, best_growth = growth;
    if (!estimateIsCurrent(peer, own_known_cells) && clock - peer.last_attempt_clock >= params_.refresh_period &&
        peer.last_attempt_clock < oldest)
      stale = id, oldest = peer.last_attempt_clock;
  }
  return best ? best : stale;
}

bool PeerRegistry::estimateIsCurrent(const Peer& peer, size_t own_known_cells) const {
  return peer.attempts > 0 && peer.known_cells == peer.known_at_estimate && own_known_cells == peer.own_known_at_estimate;
}

bool PeerRegistry::applyEstimate(const std::string& id, const FusionResult& result, size_t own_known_cells, double now,
                                 std::optional<double> clock) {
  auto it = peers_.find(id);
  if (it == peers_.end()) return false;
  Peer& peer = it->second;
  ++peer.attempts;
  peer.last_attempt_clock = clock.value_or(now);
  peer.known_at_estimate = peer.known_cells;
  peer.own_known_at_estimate = own_known_cells;
  PeerEstimate estimate{result.accepted, result.pose, result.verdict.acceptance, now, result.verdict.reason};
  peer.last_attempt = estimate;
  if (!estimate.accepted) {
    if (++peer.rejections_in_a_row >= params_.revoke_after_rejections && peer.accepted) {
      peer.accepted.reset();  // the maps grew and no longer support it
      return true;
    }
    return false;  // otherwise keep what we had
  }
  peer.rejections_in_a_row = 0;
  if (!peer.accepted) {
    peer.accepted = estimate;
    peer.accepted_since = now;
    return true;
  }
  const PeerEstimate& current = *peer.accepted;
  const bool consistent =
      std::hypot(estimate.pose.x - current.pose.x, estimate.pose.y - current.pose.y) <= params_.consistent_m &&
      std::abs(Pose2D::normalizeAngle(estimate.pose.yaw - current.pose.yaw)) <= params_.consistent_deg * M_PI / 180;
  // Same place: the newer estimate saw more of both maps, take it. Elsewhere: only when clearly better.
  if (consistent || estimate.acceptance > current.acceptance + params_.switch_margin) {
    peer.accepted = estimate;
    return true;
  }
  return false;
}

std::optional<std::string> PeerRegistry::parentOf() const {
  for (const auto& [id, peer] : peers_)  // std::map: ascending ids
    if (id < self_ && peer.accepted) return id;
  return std::nullopt;
}

}  // namespace mrslam::fusion
