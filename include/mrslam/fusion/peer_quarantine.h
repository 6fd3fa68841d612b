// Peers that keep sending maps we must refuse (ROS-free, for the map-merge nodelet).
//
// A refused map is counted against the peer that sent it; after `bad_maps_in_a_row` refusals
// in a row the peer is quarantined for `period_s`: its shares are dropped unread, so a broken
// or hostile peer costs one check per message instead of a conversion and a fusion attempt.
// One good map ends the streak. When the period ends the peer is heard again from scratch.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace mrslam::fusion {

struct PeerQuarantineParams {
  int bad_maps_in_a_row = 3;  // refusals in a row that quarantine a peer
  double period_s = 60.0;     // how long a quarantined peer is not listened to
};

class PeerQuarantine {
 public:
  explicit PeerQuarantine(const PeerQuarantineParams& params = PeerQuarantineParams{}) : params_(params) {}

  // True while `peer` is quarantined at time `now` (s, any monotonic clock).
  bool isQuarantined(const std::string& peer, double now) const;
  // A map of `peer` was refused at `now`. Returns true when this refusal starts a quarantine.
  bool reportBad(const std::string& peer, double now);
  // A map of `peer` passed every check: its streak of refusals ends.
  void reportGood(const std::string& peer);
  // Peers quarantined at `now`, for diagnostics.
  std::vector<std::string> quarantined(double now) const;
  const PeerQuarantineParams& params() const { return params_; }

 private:
  struct Record {
    int bad_in_a_row = 0;
    double until = -1;  // quarantined while now < until
  };
  PeerQuarantineParams params_;
  std::map<std::string, Record> records_;
};

}  // namespace mrslam::fusion
