// What one robot knows about its peers, for the map-merge nodelet (ROS-free, unit-tested):
// the latest map of each peer, when to re-estimate a peer's transform (its map or ours has
// grown enough), which estimate to keep (hysteresis), and which peer's map frame is the tf
// parent of ours, and where a peer whose map does not overlap ours is placed through a peer
// we accepted (a relay).
//
// Frame convention (keeps tf a tree with one publisher per edge, all robots under one master):
// robot N publishes exactly one edge, the parent of its own map frame, robotP/map -> robotN/map,
// where P is the smallest robot id below N whose map N has accepted (ids compared as strings).
// Every map frame then has at most one parent, parents always have smaller ids (no cycles),
// and a group of robots that accepted each other hangs from its smallest id.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mrslam/fusion/map_fusion.h"
#include "mrslam/grid.h"

namespace mrslam::fusion {

struct PeerRegistryParams {
  double regrow_fraction = 0.1;     // re-estimate when either map's known cells grew by this share
  double consistent_m = 0.5;        // a new estimate within this distance and...
  double consistent_deg = 3.0;      // ...this angle of the accepted one is "the same place"
  double switch_margin = 0.01;      // an inconsistent estimate replaces the accepted one only if
                                    // its acceptance index V is higher by this much
  size_t min_known_cells = 20000;   // no estimate before both maps know this many cells (50 m2 at
                                    // 0.05 m): a few scans are too little evidence either way
  double refresh_period = 10.0;     // s: a peer whose map (or ours) changed at all is re-estimated
                                    // after this long, so the final maps are always used
  int revoke_after_rejections = 3;  // an accepted transform is dropped after this many rejections
                                    // in a row on grown maps: a true overlap only gains evidence
  // Relays: a peer we cannot accept directly is aligned to the map of every peer we accepted
  // (one hop each) and placed where at least relay_min_vias of those chains agree (0: never).
  // One chain adds the errors of two estimates; two that agree are a check on each other.
  int relay_min_vias = 2;
  double relay_agree_m = 0.15;   // chains agree when they put the peer map's centre this close...
  double relay_agree_deg = 1.0;  // ...and its heading this close
};

// Why these parameters cannot be used (empty when they can): the first one out of its range,
// named as in config/merge.yaml, with its value.
std::string peerRegistryParamsProblem(const PeerRegistryParams& params);

struct PeerEstimate {
  bool accepted = false;
  Pose2D pose;              // the peer's map frame in our map frame
  double acceptance = 0;    // V
  double stamp = 0;         // when it was estimated (s)
  std::string reason;       // why rejected
};

// What the scheduling needs to know of a map: how much of it is known (growth) and a hash of
// its content (any change at all, e.g. a loop closure that moved walls without adding cells).
struct MapSummary {
  size_t known_cells = 0;
  uint64_t content = 0;
  bool operator==(const MapSummary& o) const { return known_cells == o.known_cells && content == o.content; }
  bool operator!=(const MapSummary& o) const { return !(*this == o); }
};
MapSummary summarize(const OccupancyGrid& grid);

// A peer's map aligned to the map of another peer, `via`, that we accepted directly: the same
// fusion and verification as a direct estimate, with the same hysteresis. Its poses are the
// peer's map frame in via's map frame.
struct Relay {
  MapSummary at_estimate, via_at_estimate;  // both maps when last estimated
  int attempts = 0;
  int rejections_in_a_row = 0;
  std::optional<PeerEstimate> accepted;
  PeerEstimate last_attempt;
  double last_attempt_clock = 0;
  double accepted_since = 0;
};

// Where a peer's map sits in ours: directly accepted, or through relays that agree (`vias`
// names the peers, empty when direct; the pose is then the mean of their chains).
struct Placement {
  Pose2D pose;
  double acceptance = 0;  // V of the estimate that placed it (the lowest of the relays')
  double since = 0;       // since when it has been placed (s)
  std::vector<std::string> vias;
};

struct Peer {
  std::string id;
  std::shared_ptr<const OccupancyGrid> map;  // latest valid map
  uint32_t version = 0;
  double first_seen = 0, last_seen = 0;
  MapSummary summary;                             // of `map`
  MapSummary at_estimate, own_at_estimate;        // both maps when last estimated
  int attempts = 0;
  int rejections_in_a_row = 0;
  std::optional<PeerEstimate> accepted;  // the transform in use
  PeerEstimate last_attempt;
  double last_attempt_clock = 0;         // the same on the scheduling clock (see nextToEstimate)
  double accepted_since = 0;             // when the first transform was accepted
  std::map<std::string, Relay> relays;   // this peer's map aligned to accepted peers', by their id
};

size_t knownCells(const OccupancyGrid& grid);

// A robot id names tf frames (robotN/map), so it must read as one tf prefix:
// [a-zA-Z][a-zA-Z0-9_]*, at most 64 characters.
bool isValidRobotId(const std::string& id);

class PeerRegistry {
 public:
  explicit PeerRegistry(std::string self_id, const PeerRegistryParams& params = PeerRegistryParams{});

  // A new map from a peer. A version lower than the last one means the peer restarted: its map
  // frame is new, so what we knew about it is dropped. Returns true when the peer is new or rejoined.
  bool updatePeer(const std::string& id, std::shared_ptr<const OccupancyGrid> map, uint32_t version, double now);
  // Drops all we know about a peer (its map could not be fused after all).
  void forget(const std::string& id);
  // The peer whose transform should be (re-)estimated next, given our map: never estimated
  // first, then the one whose maps grew the most, then one whose maps changed at all (content,
  // not only size) and whose estimate is older than refresh_period on the scheduling `clock`.
  // None when nothing needs work. The nodelet's clock is the wall clock: refreshing is a CPU
  // budget, and a bag's clock stops at its end, which would leave the final maps unmerged.
  std::optional<std::string> nextToEstimate(const MapSummary& own, double clock) const;
  // Records an estimate with hysteresis. Returns true when the transform in use changed
  // (replaced or revoked).
  // (replaced or revoked). `now` stamps the estimate (ROS time); `clock` is the scheduling clock
  // of nextToEstimate (defaults to now).
  bool applyEstimate(const std::string& id, const FusionResult& result, const MapSummary& own, double now,
                     std::optional<double> clock = std::nullopt);
  // True when the transform in use was estimated on both maps as they are now: neither changed
  // since the last estimate, and that estimate was not a rejection (a transform kept from older
  // maps through hysteresis is not current). A relayed peer's: every relay used and every via's.
  bool estimateIsCurrent(const Peer& peer, const MapSummary& own) const;
  // The next relay to estimate, as {peer, via}, when no direct estimate is due: a peer we have
  // not accepted, aligned to a peer we have (never tried first, then grown maps, then any change
  // after refresh_period, as for direct estimates). None when relays are off or nothing needs work.
  std::optional<std::pair<std::string, std::string>> nextRelayToEstimate(double clock) const;
  // Records a relay estimate (the peer's map in via's) with the hysteresis of applyEstimate.
  // Returns true when the relay changed.
  bool applyRelayEstimate(const std::string& id, const std::string& via, const FusionResult& result, double now,
                          std::optional<double> clock = std::nullopt);
  // Where the peer's map sits in ours: its accepted transform, or else the mean of the largest
  // group of relay chains (accepted relays through peers we accept) that agree with each other,
  // when it has at least relay_min_vias of them. None when it is not placed.
  std::optional<Placement> placementOf(const Peer& peer) const;
  // Our map frame's tf parent under the convention above (direct accepts only).
  std::optional<std::string> parentOf() const;

  const std::map<std::string, Peer>& peers() const { return peers_; }
  const std::string& self() const { return self_; }

 private:
  std::string self_;
  PeerRegistryParams params_;
  std::map<std::string, Peer> peers_;
};

}  // namespace mrslam::fusion
