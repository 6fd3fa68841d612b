// Whether a scan's stamp can be used: the SLAM nodelet's rules for stamps, free of ROS.
//
// A scan stamped 0, far ahead or far back is refused, so that one stray stamp neither leaves
// every later scan looking "back in time" nor wipes the map. Time going back for several scans
// in a row is a bag that restarted: the robot starts a new map.
//
// "Far ahead" is judged against the later of the clock and the last scan used, not against the
// clock alone. A clock can lag the data it comes with: `rosbag play --clock` stops publishing
// /clock for seconds while it catches up under load and keeps publishing the messages
// (ros/ros_comm#82, #1117). Scans that follow the last one in a normal stride are the robot's
// next scans whatever the clock says; a stamp far ahead of both is a glitch.
#pragma once

#include <optional>
#include <string>

namespace mrslam {

struct ScanStampRules {
  double max_time_jump = 1.0;      // s: a scan stamped this much before the last one is refused...
  int restart_scans = 3;           // ...unless this many in a row are: the bag restarted
  double future_tolerance = 10.0;  // s: a scan further ahead of the clock and the last scan is refused
};

struct StampVerdict {
  enum class Kind { kUse, kRefuse, kRestart };
  Kind kind = Kind::kUse;
  std::string reason;    // why a scan is refused or the map restarts
  double clock_lag = 0;  // s the scan is ahead of the clock (0 when the clock is unknown)
};

class ScanStampGate {
 public:
  explicit ScanStampGate(const ScanStampRules& rules) : rules_(rules) {}

  // The verdict on a scan stamped `t` (seconds; 0 = unstamped) when the clock reads `now`
  // (0 = no clock yet, as under simulated time before the first /clock). After kRestart the
  // caller starts a new map; the gate has forgotten the old scans.
  StampVerdict check(double t, double now);
  // The scan stamped `t` was used: later scans are judged against it.
  void used(double t) { last_ = t; }
  // The stamp of the last scan used, if any since the start or the last restart.
  const std::optional<double>& last() const { return last_; }
  const ScanStampRules& rules() const { return rules_; }

 private:
  ScanStampRules rules_;
  std::optional<double> last_;
  int going_back_ = 0;       // scans in a row stamped before the last one used
  double last_back_ = 0;     // the stamp of the latest of them
};

}  // namespace mrslam
