#include "mrslam/fusion/peer_registry.h"

#include <algorithm>

namespace mrslam::fusion {

size_t knownCells(const OccupancyGrid& grid) {
  return static_cast<size_t>(std::count_if(grid.data.begin(), grid.data.end(), [](int8_t v) { return v >= 0; }));
}

MapSummary summarize(const OccupancyGrid& grid) {
  // FNV-1a over the cells and the geometry.
  uint64_t h = 1469598103934665603ull;
  auto mix = [&h](const void* data, size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  };
  mix(grid.data.data(), grid.data.size());
  for (double v : {static_cast<double>(grid.width), static_cast<double>(grid.height), grid.resolution, grid.origin.x,
                   grid.origin.y, grid.origin.yaw})
    mix(&v, sizeof v);
  return {knownCells(grid), h};
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
  peer.summary = summarize(*peer.map);
  return rejoined;
}

std::optional<std::string> PeerRegistry::nextToEstimate(const MapSummary& own, double clock) const {
  std::optional<std::string> best, stale;
  double best_growth = 0, oldest = clock;
  auto growth = [](size_t now, size_t then) { return then ? static_cast<double>(now) / then - 1 : 1.0; };
  for (const auto& [id, peer] : peers_) {
    if (!peer.map || own.known_cells < params_.min_known_cells || peer.summary.known_cells < params_.min_known_cells)
      continue;
    if (peer.attempts == 0) return id;
    const double grew = std::max(growth(peer.summary.known_cells, peer.at_estimate.known_cells),
                                 growth(own.known_cells, peer.own_at_estimate.known_cells));
    if (grew >= params_.regrow_fraction && grew > best_growth) best = id, best_growth = grew;
    const bool changed = peer.summary != peer.at_estimate || own != peer.own_at_estimate;
    if (changed && clock - peer.last_attempt_clock >= params_.refresh_period && peer.last_attempt_clock < oldest)
      stale = id, oldest = peer.last_attempt_clock;
  }
  return best ? best : stale;
}

bool PeerRegistry::estimateIsCurrent(const Peer& peer, const MapSummary& own) const {
  const bool unchanged = peer.attempts > 0 && peer.summary == peer.at_estimate && own == peer.own_at_estimate;
  return unchanged && (peer.last_attempt.accepted || !peer.accepted);
}

bool PeerRegistry::applyEstimate(const std::string& id, const FusionResult& result, const MapSummary& own, double now,
                                 std::optional<double> clock) {
  auto it = peers_.find(id);
  if (it == peers_.end()) return false;
  Peer& peer = it->second;
  ++peer.attempts;
  peer.last_attempt_clock = clock.value_or(now);
  peer.at_estimate = peer.summary;
  peer.own_at_estimate = own;
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
