#include "mrslam/fusion/peer_registry.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace mrslam::fusion {
namespace {

// Relay chains of one peer weighed against each other: every subset of the first this many
// (by via id) is tried, 2^8 at most.
constexpr size_t kMaxChains = 8;

// The share by which a map grew since it was last estimated (1 when it had nothing then).
double growth(size_t now, size_t then) { return then ? static_cast<double>(now) / then - 1 : 1.0; }

// The next estimate among candidates that were each estimated before on two maps (a direct
// estimate: the peer's and ours; a relay: the peer's and the via's): the one whose maps grew
// the most, by regrow_fraction at least; else the one whose maps changed at all and whose last
// estimate is the oldest, older than refresh_period on the scheduling clock.
template <typename Key>
class NextEstimate {
 public:
  NextEstimate(const PeerRegistryParams& params, double clock) : params_(params), clock_(clock), oldest_(clock) {}
  void consider(const Key& key, const MapSummary& a, const MapSummary& a_then, const MapSummary& b,
                const MapSummary& b_then, double last_clock) {
    const double grew = std::max(growth(a.known_cells, a_then.known_cells), growth(b.known_cells, b_then.known_cells));
    if (grew >= params_.regrow_fraction && grew > best_growth_) best_ = key, best_growth_ = grew;
    const bool changed = a != a_then || b != b_then;
    if (changed && clock_ - last_clock >= params_.refresh_period && last_clock < oldest_) stale_ = key, oldest_ = last_clock;
  }
  std::optional<Key> pick() const { return best_ ? best_ : stale_; }

 private:
  const PeerRegistryParams& params_;
  double clock_, oldest_, best_growth_ = 0;
  std::optional<Key> best_, stale_;
};

// The hysteresis every estimate goes through, direct or relayed: an acceptance clears the run of
// rejections; the first is taken, a consistent one refines the one in use, one elsewhere
// replaces it only when clearly better; a run of rejections on grown maps revokes it. Returns
// true when `accepted` changed.
bool applyHysteresis(std::optional<PeerEstimate>& accepted, int& rejections_in_a_row, double& accepted_since,
                     const PeerEstimate& estimate, const PeerRegistryParams& params) {
  if (!estimate.accepted) {
    if (++rejections_in_a_row >= params.revoke_after_rejections && accepted) {
      accepted.reset();  // the maps grew and no longer support it
      return true;
    }
    return false;  // otherwise keep what we had
  }
  rejections_in_a_row = 0;
  if (!accepted) {
    accepted = estimate;
    accepted_since = estimate.stamp;
    return true;
  }
  const PeerEstimate& current = *accepted;
  const bool consistent =
      std::hypot(estimate.pose.x - current.pose.x, estimate.pose.y - current.pose.y) <= params.consistent_m &&
      std::abs(Pose2D::normalizeAngle(estimate.pose.yaw - current.pose.yaw)) <= params.consistent_deg * M_PI / 180;
  // Same place: the newer estimate saw more of both maps, take it. Elsewhere: only when clearly better.
  if (consistent || estimate.acceptance > current.acceptance + params.switch_margin) {
    accepted = estimate;
    return true;
  }
  return false;
}

}  // namespace

std::string peerRegistryParamsProblem(const PeerRegistryParams& p) {
  struct Check {
    const char* key;
    double value;
    bool ok;
    const char* range;
  };
  const Check checks[] = {
      {"regrow_fraction", p.regrow_fraction, p.regrow_fraction > 0, "> 0"},
      {"consistent_m", p.consistent_m, p.consistent_m >= 0, ">= 0"},
      {"consistent_deg", p.consistent_deg, p.consistent_deg >= 0 && p.consistent_deg <= 180, "in [0, 180]"},
      {"switch_margin", p.switch_margin, p.switch_margin >= 0, ">= 0"},
      {"refresh_period", p.refresh_period, p.refresh_period > 0, "> 0"},
      {"revoke_after_rejections", static_cast<double>(p.revoke_after_rejections), p.revoke_after_rejections >= 1, ">= 1"},
      {"relay_min_vias", static_cast<double>(p.relay_min_vias),
       p.relay_min_vias >= 0 && p.relay_min_vias <= static_cast<int>(kMaxChains), "in [0, 8]"},
      {"relay_agree_m", p.relay_agree_m, p.relay_agree_m > 0, "> 0"},
      {"relay_agree_deg", p.relay_agree_deg, p.relay_agree_deg > 0 && p.relay_agree_deg <= 180, "in (0, 180]"},
  };
  for (const Check& c : checks)
    if (!c.ok)  // NaN fails every range too
      return std::string(c.key) + " must be " + c.range + " (got " + std::to_string(c.value) + ")";
  return "";
}

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
    for (auto& [other_id, other] : peers_) other.relays.erase(id);  // aligned to its old frame
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

void PeerRegistry::forget(const std::string& id) {
  peers_.erase(id);
  for (auto& [other_id, other] : peers_) other.relays.erase(id);
}

std::optional<std::string> PeerRegistry::nextToEstimate(const MapSummary& own, double clock) const {
  NextEstimate<std::string> next(params_, clock);
  for (const auto& [id, peer] : peers_) {
    if (!peer.map || own.known_cells < params_.min_known_cells || peer.summary.known_cells < params_.min_known_cells)
      continue;
    if (peer.attempts == 0) return id;
    next.consider(id, peer.summary, peer.at_estimate, own, peer.own_at_estimate, peer.last_attempt_clock);
  }
  return next.pick();
}

bool PeerRegistry::estimateIsCurrent(const Peer& peer, const MapSummary& own) const {
  const std::optional<Placement> placed = peer.accepted ? std::nullopt : placementOf(peer);
  if (placed) {  // relayed: every relay used and every via's own transform describe today's maps
    for (const std::string& via_id : placed->vias) {
      const Peer& via = peers_.at(via_id);
      const Relay& relay = peer.relays.at(via_id);
      if (!relay.last_attempt.accepted || peer.summary != relay.at_estimate || via.summary != relay.via_at_estimate ||
          !estimateIsCurrent(via, own))
        return false;
    }
    return true;
  }
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
  return applyHysteresis(peer.accepted, peer.rejections_in_a_row, peer.accepted_since, estimate, params_);
}

std::optional<std::pair<std::string, std::string>> PeerRegistry::nextRelayToEstimate(double clock) const {
  if (params_.relay_min_vias <= 0) return std::nullopt;
  NextEstimate<std::pair<std::string, std::string>> next(params_, clock);
  for (const auto& [id, peer] : peers_) {
    if (peer.accepted || !peer.map || peer.summary.known_cells < params_.min_known_cells) continue;
    size_t vias = 0;  // placementOf weighs the chains through the first kMaxChains: no work beyond
    for (const auto& [via_id, via] : peers_) {
      if (via_id == id || !via.accepted || !via.map || via.summary.known_cells < params_.min_known_cells) continue;
      if (++vias > kMaxChains) break;
      const auto it = peer.relays.find(via_id);
      if (it == peer.relays.end() || it->second.attempts == 0) return std::make_pair(id, via_id);
      const Relay& relay = it->second;
      next.consider(std::make_pair(id, via_id), peer.summary, relay.at_estimate, via.summary, relay.via_at_estimate,
                    relay.last_attempt_clock);
    }
  }
  return next.pick();
}

bool PeerRegistry::applyRelayEstimate(const std::string& id, const std::string& via, const FusionResult& result,
                                      double now, std::optional<double> clock) {
  auto it = peers_.find(id), via_it = peers_.find(via);
  if (it == peers_.end() || via_it == peers_.end() || id == via) return false;
  Relay& relay = it->second.relays[via];
  ++relay.attempts;
  relay.last_attempt_clock = clock.value_or(now);
  relay.at_estimate = it->second.summary;
  relay.via_at_estimate = via_it->second.summary;
  relay.last_attempt = {result.accepted, result.pose, result.verdict.acceptance, now, result.verdict.reason};
  return applyHysteresis(relay.accepted, relay.rejections_in_a_row, relay.accepted_since, relay.last_attempt,
                         params_);
}

std::optional<Placement> PeerRegistry::placementOf(const Peer& peer) const {
  if (peer.accepted) return Placement{peer.accepted->pose, peer.accepted->acceptance, peer.accepted_since, {}};
  if (params_.relay_min_vias <= 0 || !peer.map) return std::nullopt;
  struct Chain {
    const std::string* via;
    Pose2D pose;
    double acceptance, since;
  };
  std::vector<Chain> chains;  // through peers we accept, ascending ids
  for (const auto& [via_id, relay] : peer.relays) {
    const auto via = peers_.find(via_id);
    if (!relay.accepted || via == peers_.end() || !via->second.accepted) continue;
    if (chains.size() == kMaxChains) break;
    chains.push_back({&via_id, via->second.accepted->pose.compose(relay.accepted->pose), relay.accepted->acceptance,
                      std::max(relay.accepted_since, via->second.accepted_since)});
  }
  if (chains.size() < static_cast<size_t>(params_.relay_min_vias)) return std::nullopt;
  // Chains agree when they put the peer map's centre and heading close together.
  const OccupancyGrid& map = *peer.map;
  double cx, cy;
  map.origin.apply(map.width * map.resolution / 2, map.height * map.resolution / 2, cx, cy);
  auto agree = [&](const Pose2D& p, const Pose2D& q) {
    double px, py, qx, qy;
    p.apply(cx, cy, px, py);
    q.apply(cx, cy, qx, qy);
    return std::hypot(px - qx, py - qy) <= params_.relay_agree_m &&
           std::abs(Pose2D::normalizeAngle(p.yaw - q.yaw)) <= params_.relay_agree_deg * M_PI / 180;
  };
  // The largest group of chains that agree pairwise (a team has a handful of peers: every subset).
  uint32_t best = 0;
  for (uint32_t group = 1; group < (1u << chains.size()); ++group) {
    if (__builtin_popcount(group) <= __builtin_popcount(best)) continue;
    bool consistent = true;
    for (size_t i = 0; i < chains.size() && consistent; ++i)
      for (size_t j = i + 1; j < chains.size() && consistent; ++j)
        if ((group >> i & 1) && (group >> j & 1)) consistent = agree(chains[i].pose, chains[j].pose);
    if (consistent) best = group;
  }
  if (__builtin_popcount(best) < params_.relay_min_vias) return std::nullopt;
  Placement placed{{}, 1.0, 0.0, {}};
  double sin_sum = 0, cos_sum = 0;
  for (size_t i = 0; i < chains.size(); ++i) {
    if (!(best >> i & 1)) continue;
    placed.pose.x += chains[i].pose.x;
    placed.pose.y += chains[i].pose.y;
    sin_sum += std::sin(chains[i].pose.yaw);
    cos_sum += std::cos(chains[i].pose.yaw);
    placed.acceptance = std::min(placed.acceptance, chains[i].acceptance);
    placed.since = std::max(placed.since, chains[i].since);
    placed.vias.push_back(*chains[i].via);
  }
  placed.pose.x /= placed.vias.size();
  placed.pose.y /= placed.vias.size();
  placed.pose.yaw = std::atan2(sin_sum, cos_sum);
  return placed;
}

std::optional<std::string> PeerRegistry::parentOf() const {
  for (const auto& [id, peer] : peers_)  // std::map: ascending ids
    if (id < self_ && peer.accepted) return id;
  return std::nullopt;
}

}  // namespace mrslam::fusion
