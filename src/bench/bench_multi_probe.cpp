// mrslam_bench_multi_probe N SECONDS: watches a running multi-robot stack (robot1..robotN) for
// SECONDS of wall time, or until SIGUSR1 (the harness's word that every bag has played and the
// mergers had their time to settle), and prints, as key=value lines: the simulated time that passed (so the
// real-time factor achieved), the poses each robot published, how many robot pairs are merged,
// and for each merged pair the simulated time from the peer's first map to the accepted transform
// and whether the accepted transform is correct (within 1 degree and 2 cells of the truth from
// the bag's reference poses, mrslam/bench/peer_frame_truth.h), and the bytes each robot put on
// the link between robots (the compressed share topic; new maps, keyframes apart) per second of
// the bag's clock: mean over robots, the busiest robot's mean, and the most any robot sent in
// 10 s of the bag's clock. Per robot, from its SLAM nodelet's last diagnostics: how long its
// poses came after their scans arrived (wall s) and how many scans waited for, or went without,
// the gyro; from its merger's: how often it re-made its share subscriptions. One "pair robotA <-
// robotB ..." line per ordered pair it saw in a merge_status (accepted, delay, correct, stale:
// as the last status said; when not accepted, the merger's attempts, the relays it tried and
// its last reason; when accepted, how long after the probe started the merger first heard the
// peer (heard_after_s, -1: not since), when a status called it stale again after that
// (stale_again_after_s, -1: never), how old the merger's last status was as the probe ended
// (status_age_s), how long before that status the merger had last read its share links
// (link_checked_s_ago), and what led to the accept: when the merger stamped the
// peer's first map on its own clock, the first try's delay, the tries up to the accept and the
// last rejection's reason).
// Given the log the bag was made from (third argument), each accepted pair's line also gives its
// error against the truth the robots' scans fix (mrslam/bench/scan_fixed_frame.h).
// The clock it reads is /clock (remap it to follow one robot's clock).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <mrslam/CompressedMapShare.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <tf2/utils.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "mrslam/bench/peer_frame_truth.h"
#include "mrslam/bench/scan_fixed_frame.h"
#include "mrslam/slam/robot_log.h"

namespace {
mrslam::Pose2D toPose(const geometry_msgs::Pose& p) {
  return {p.position.x, p.position.y, tf2::getYaw(p.orientation)};
}
// merge_status names a relayed pair's vias separated by spaces: one field here, "direct" when none.
std::string viaField(std::string via) {
  if (via.empty()) return "direct";
  std::replace(via.begin(), via.end(), ' ', ',');
  return via;
}
// merge_status's relays ("robot1 3 accepted; robot2 2 rejected: <reason>") as one field without
// the reasons: "robot1:3:accepted,robot2:2:rejected".
std::string compactRelays(const std::string& relays) {
  std::string out;
  std::istringstream entries(relays);
  std::string entry;
  while (std::getline(entries, entry, ';')) {
    std::istringstream words(entry);
    std::string via, tries, verdict;
    if (!(words >> via >> tries >> verdict)) continue;
    if (!verdict.empty() && verdict.back() == ':') verdict.pop_back();
    out += (out.empty() ? "" : ",") + via + ":" + tries + ":" + verdict;
  }
  return out;
}

struct PairStatus {
  bool accepted = false;
  double delay = -1;  // simulated s from the peer's first map to the accepted transform
  mrslam::Pose2D pose;
  bool current = false;  // the estimate was made on both maps as they are now
  bool stale = false;    // the merger has heard nothing from the peer for stale_after
  double heard_s_ago = -1;  // wall s since the merger last heard from the peer
  // Wall s from the probe's start to the first time the merger heard the peer after it (-1:
  // not since): run as a link comes back, how long the peer took to be heard again.
  double heard_after = -1;
  // Wall s from the probe's start to the first status that called the peer stale again after
  // it had been heard (-1: never), and to the last status from this merger: a merger that
  // heard a peer come back and lost it again tells that from one whose status stopped coming.
  double stale_again_after = -1;
  double last_status_at = -1;
  double link_silent = -1;  // s since data last arrived on the merger's connection to the peer (-1: none open)
  double link_checked = -1;  // s since the merger last read its share links (once a second; -1: not said)
  std::string attempts, why;  // when not accepted: how often the merger tried, and its last reason
  std::string relays;         // when not accepted: each via tried, "via:tries:accepted|rejected"
  std::string via;            // the peers a relayed pair is placed through (empty: direct)
  // What led to the first accept: the simulated s from the peer's first map to the merger's
  // first try, the merger's tries up to the accept, and the last reason it rejected before.
  double first_try = -1;
  int tries_to_accept = 0;
  double first_map_time = -1;  // the merger's stamp of the peer's first map (its clock, s)
  std::string last_rejection;
};
// The most bytes per second any one robot sent over any `window` seconds of the bag's clock.
double peakRate(const std::map<std::string, std::vector<std::pair<double, double>>>& log, double window) {
  double peak = 0;
  for (const auto& [id, sends] : log) {
    double sum = 0;
    size_t first = 0;
    for (size_t i = 0; i < sends.size(); ++i) {
      sum += sends[i].second;
      while (sends[i].first - sends[first].first >= window) sum -= sends[first++].second;
      peak = std::max(peak, sum / window);
    }
  }
  return peak;
}

// With the log the bag was made from: the accepted pair's error against the truth the robots'
// scans fix where both saw one place (scan_fixed_frame.h) and that truth's own spread, as fields
// of its line ("scan_cells=none" when too few scan pairs relate the two robots).
std::string scanFixedFields(const mrslam::slam::RobotLog* log, const mrslam::bench::RobotTrack& n,
                            const mrslam::bench::RobotTrack& m, const mrslam::Pose2D& estimate) {
  if (!log) return "";
  const auto truth = mrslam::bench::scanFixedPeerFrame(*log, n, m);
  if (!truth) return " scan_cells=none";
  const auto e = mrslam::bench::frameErrorAgainst(estimate, truth->truth, m);
  char text[160];
  std::snprintf(text, sizeof(text), " scan_cells=%.2f scan_deg=%.2f scan_relations=%zu scan_spread_cells=%.2f",
                e.metres / 0.05, e.yaw_deg, truth->relations, truth->spread_m / 0.05);
  return text;
}
}  // namespace

std::atomic<bool> g_told_to_finish{false};
void finishNow(int) { g_told_to_finish = true; }

int main(int argc, char** argv) {
  ros::init(argc, argv, "mrslam_bench_multi_probe", ros::init_options::AnonymousName);
  std::signal(SIGUSR1, finishNow);
  if (argc < 3 || argc > 4) {
    std::fprintf(stderr, "usage: mrslam_bench_multi_probe N SECONDS (at most; SIGUSR1 ends it sooner) [LOG the bag was made from]\n");
    return 2;
  }
  const int robots = std::atoi(argv[1]);
  const double seconds = std::atof(argv[2]);
  // A log that cannot be read is refused before the run, not after it.
  if (argc == 4 && !std::ifstream(argv[3])) {
    std::fprintf(stderr, "mrslam_bench_multi_probe: cannot read the log %s\n", argv[3]);
    return 2;
  }
  ros::NodeHandle nh;
  const ros::WallTime start = ros::WallTime::now();
  std::mutex mutex;
  std::map<int, mrslam::bench::RobotTrack> tracks;
  std::map<std::pair<int, std::string>, PairStatus> pairs;
  double first_clock = -1, last_clock = -1;
  ros::WallTime first_wall, last_wall;
  std::vector<ros::Subscriber> subs;
  subs.push_back(nh.subscribe<rosgraph_msgs::Clock>("/clock", 10, [&](const rosgraph_msgs::Clock::ConstPtr& c) {
    std::lock_guard<std::mutex> lock(mutex);
    if (first_clock < 0) first_clock = c->clock.toSec(), first_wall = ros::WallTime::now();
    if (c->clock.toSec() > last_clock) last_clock = c->clock.toSec(), last_wall = ros::WallTime::now();
  }));
  for (int k = 1; k <= robots; ++k) {
    const std::string r = "/robot" + std::to_string(k);
    subs.push_back(nh.subscribe<geometry_msgs::PoseWithCovarianceStamped>(
        r + "/pose", 100, [&, k](const geometry_msgs::PoseWithCovarianceStamped::ConstPtr& m) {
          std::lock_guard<std::mutex> lock(mutex);
          tracks[k].estimate[m->header.stamp.toNSec()] = toPose(m->pose.pose);
        }));
    subs.push_back(nh.subscribe<geometry_msgs::PoseStamped>(
        r + "/reference_pose", 100, [&, k](const geometry_msgs::PoseStamped::ConstPtr& m) {
          std::lock_guard<std::mutex> lock(mutex);
          tracks[k].reference[m->header.stamp.toNSec()] = toPose(m->pose);
        }));
    subs.push_back(nh.subscribe<diagnostic_msgs::DiagnosticArray>(
        r + "/merge_status", 10, [&, k](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
          std::lock_guard<std::mutex> lock(mutex);
          for (const auto& s : m->status) {
            std::map<std::string, std::string> v;
            for (const auto& kv : s.values) v[kv.key] = kv.value;
            PairStatus& p = pairs[{k, s.name}];
            const bool was_accepted = p.accepted;
            p.accepted = v["accepted"] == "True";
            p.stale = v["stale"] == "True";
            // A figure an older merger does not report reads -1.
            const auto figure = [&v](const char* key) { return v.count(key) ? std::stod(v[key]) : -1.0; };
            p.heard_s_ago = figure("heard_s_ago");
            const double since_start = (ros::WallTime::now() - start).toSec();
            if (p.heard_after < 0 && p.heard_s_ago >= 0 && p.heard_s_ago < since_start)
              p.heard_after = since_start - p.heard_s_ago;
            if (p.heard_after >= 0 && p.stale && p.stale_again_after < 0) p.stale_again_after = since_start;
            p.last_status_at = since_start;
            p.link_silent = figure("link_silent_s");
            p.link_checked = figure("link_checked_s_ago");
            p.attempts = v["attempts"];
            p.relays = compactRelays(v["relays"]);
            p.why = s.message;
            const int tries = std::atoi(p.attempts.c_str());
            p.first_map_time = std::stod(v["first_map_time"]);
            if (p.first_try < 0 && tries > 0) p.first_try = std::stod(v["last_estimate_time"]) - p.first_map_time;
            if (!p.accepted && p.tries_to_accept == 0 && s.message != "not accepted: ") p.last_rejection = s.message;
            if (p.accepted && !was_accepted && p.tries_to_accept == 0) p.tries_to_accept = tries;
            if (p.accepted) {
              p.delay = std::stod(v["accepted_since"]) - p.first_map_time;
              p.pose = {std::stod(v["x"]), std::stod(v["y"]), std::stod(v["yaw"])};
              p.via = v["via"];
              p.current = v["estimate_current"] == "True";
            }
          }
        }));
  }
  std::map<int, std::map<std::string, std::string>> slam_status;   // robot -> its SLAM nodelet's last values
  std::map<int, std::map<std::string, std::string>> merge_status;  // robot -> its merger's last values
  subs.push_back(nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 100, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
        std::lock_guard<std::mutex> lock(mutex);
        for (const auto& s : m->status) {
          // The nodelets' updaters name their hardware after the robot's namespace.
          if (s.hardware_id.rfind("/robot", 0) != 0) continue;
          const int k = std::atoi(s.hardware_id.c_str() + 6);
          if (s.name.find("slam") != std::string::npos)
            for (const auto& kv : s.values) slam_status[k][kv.key] = kv.value;
          else if (s.name.find("map merge") != std::string::npos)
            for (const auto& kv : s.values) merge_status[k][kv.key] = kv.value;
        }
      }));
  std::map<std::string, uint32_t> share_version;
  std::map<std::string, std::vector<std::pair<double, double>>> share_log;  // (bag s, bytes) per robot
  subs.push_back(nh.subscribe<mrslam::CompressedMapShare>("/mrslam/map_share_z", 100, [&](const mrslam::CompressedMapShare::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    if (m->version <= share_version[m->robot_id]) return;  // a keyframe: the same map again
    share_version[m->robot_id] = m->version;
    share_log[m->robot_id].emplace_back(ros::Time::now().toSec(), ros::serialization::serializationLength(*m));
  }));
  ros::AsyncSpinner spinner(2);
  spinner.start();
  while (!g_told_to_finish && (ros::WallTime::now() - start).toSec() < seconds) ros::WallDuration(0.2).sleep();
  const double wall = (ros::WallTime::now() - start).toSec();
  // Read once the robots are done (a second or two of a core), not while they run.
  std::optional<mrslam::slam::RobotLog> log;
  if (argc == 4) {
    try {
      log = mrslam::slam::readRobotLog(argv[3]);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "mrslam_bench_multi_probe: %s: %s\n", argv[3], e.what());
      return 2;
    }
  }
  std::lock_guard<std::mutex> lock(mutex);
  // The real-time factor over the time the clock was running (the bag playing).
  const double played_wall = first_clock >= 0 ? (last_wall - first_wall).toSec() : 0.0;
  std::printf("wall_s=%.1f sim_s=%.1f played_wall_s=%.1f\n", wall,
              last_clock > first_clock ? last_clock - first_clock : 0.0, played_wall);
  std::map<int, std::optional<mrslam::Pose2D>> world;
  std::map<int, double> rms;
  for (int k = 1; k <= robots; ++k) {
    world[k] = mrslam::bench::frameInWorld(tracks[k], 20, &rms[k]);
    std::printf("poses_robot%d=%zu\n", k, tracks[k].estimate.size());
    if (world[k]) std::printf("truth_fit_rms_robot%d=%.3f\n", k, rms[k]);
    auto& v = slam_status[k];
    if (!v.empty())
      std::printf("slam_robot%d pose_lag_mean_s=%s pose_lag_max_s=%s scans_waited_for_gyro=%s scans_without_gyro=%s\n", k,
                  v["pose lag behind its scan's arrival, mean of the last 100 (wall s)"].c_str(),
                  v["pose lag behind its scan's arrival, most ever (wall s)"].c_str(), v["scans that waited for the gyro"].c_str(),
                  v["scans the gyro did not cover"].c_str());
    // How often the merger re-made its share subscriptions (its log warns of the first only).
    const auto reconnects = merge_status[k].find("share reconnects (a stale peer's link was silent too)");
    if (reconnects != merge_status[k].end())
      std::printf("merge_robot%d share_reconnects=%s\n", k, reconnects->second.c_str());
  }
  int accepted = 0, total = 0, correct = 0, unchecked = 0, relayed = 0;
  std::vector<double> delays;
  for (const auto& [key, value] : pairs) {
    if (key.second.rfind("robot", 0) != 0) continue;
    ++total;
    const int peer = std::atoi(key.second.c_str() + 5);
    // The truth on every line, as x,y,yaw of the peer's map frame in ours: any pair can be
    // replayed on the maps its merger recorded (record_dir) and checked against it.
    std::string truth = "unknown";
    if (world[key.first] && world.count(peer) && world[peer]) {
      const mrslam::Pose2D t = mrslam::bench::peerFrameError(mrslam::Pose2D{}, *world[key.first], *world[peer], tracks[peer]).truth;
      char text[96];
      std::snprintf(text, sizeof(text), "%.4f,%.4f,%.5f", t.x, t.y, t.yaw);
      truth = text;
    }
    if (!value.accepted) {
      std::printf("pair robot%d <- %s accepted=0 stale=%d heard_s_ago=%.1f link_silent_s=%.1f attempts=%s relays=%s "
                  "truth=%s why=%s\n",
                  key.first, key.second.c_str(), value.stale ? 1 : 0, value.heard_s_ago, value.link_silent,
                  value.attempts.c_str(), value.relays.empty() ? "none" : value.relays.c_str(), truth.c_str(),
                  value.why.c_str());
      continue;
    }
    ++accepted, delays.push_back(value.delay);
    if (!world[key.first] || world.count(peer) == 0 || !world[peer]) {
      ++unchecked;
      std::printf("pair robot%d <- %s accepted=1 delay_s=%.1f correct=unchecked stale=%d heard_s_ago=%.1f heard_after_s=%.1f "
                  "stale_again_after_s=%.1f status_age_s=%.1f link_silent_s=%.1f link_checked_s_ago=%.1f\n",
                  key.first, key.second.c_str(), value.delay, value.stale ? 1 : 0, value.heard_s_ago, value.heard_after,
                  value.stale_again_after, wall - value.last_status_at, value.link_silent, value.link_checked);
      continue;
    }
    const auto e = mrslam::bench::peerFrameError(value.pose, *world[key.first], *world[peer], tracks[peer]);
    const double cells = e.metres / 0.05;  // map_resolution in config/robot.yaml
    const bool right = e.yaw_deg <= 1.0 && cells <= 2.0;
    // The truth is only as good as the two robots' fits to the reference (their drift): an
    // error within twice their combined residual cannot be told from a perfect estimate (the
    // bar of MergeRegressions and of the multi-run truth in bench_merge).
    const double fit_rms_cells = std::hypot(rms[key.first], rms[peer]) / 0.05;
    const double truth_bar = std::max(2.0, 2.0 * fit_rms_cells);
    std::printf("pair robot%d <- %s accepted=1 delay_s=%.1f correct=%d stale=%d heard_s_ago=%.1f heard_after_s=%.1f "
                "stale_again_after_s=%.1f status_age_s=%.1f link_silent_s=%.1f link_checked_s_ago=%.1f deg=%.2f cells=%.2f truth_bar_cells=%.2f truth=%s%s first_map_s=%.1f first_try_s=%.1f tries=%d via=%s before=%s\n",
                key.first, key.second.c_str(), value.delay, right ? 1 : 0, value.stale ? 1 : 0, value.heard_s_ago,
                value.heard_after, value.stale_again_after, wall - value.last_status_at, value.link_silent, value.link_checked, e.yaw_deg, cells, truth_bar, truth.c_str(),
                scanFixedFields(log ? &*log : nullptr, tracks[key.first], tracks[peer], value.pose).c_str(),
                value.first_map_time, value.first_try, value.tries_to_accept, viaField(value.via).c_str(),
                value.last_rejection.empty() ? "none" : value.last_rejection.c_str());
    relayed += !value.via.empty();
    if (right) {
      ++correct;
    } else {
      // With both poses, so the pair can be replayed offline on the saved maps (scripts/bench_multi).
      std::printf("outside robot%d <- %s: %.2f deg, %.2f cells (truth fit rms of the two robots: %.2f cells%s)"
                  " estimate %.3f %.3f %.4f truth %.3f %.3f %.4f\n",
                  key.first, key.second.c_str(), e.yaw_deg, cells, fit_rms_cells,
                  value.current ? "" : "; estimate made on older maps", value.pose.x, value.pose.y, value.pose.yaw,
                  e.truth.x, e.truth.y, e.truth.yaw);
    }
  }
  std::sort(delays.begin(), delays.end());
  if (last_clock > first_clock && !share_log.empty()) {
    double sum = 0, most = 0;
    for (const auto& [id, sends] : share_log) {
      double bytes = 0;
      for (const auto& send : sends) bytes += send.second;
      sum += bytes, most = std::max(most, bytes);
    }
    const double sim = last_clock - first_clock;
    std::printf("share_kb_per_s mean=%.1f max=%.1f peak_10s=%.1f\n", sum / share_log.size() / sim / 1000,
                most / sim / 1000, peakRate(share_log, 10.0) / 1000);
  }
  std::printf("pairs_seen=%d pairs_accepted=%d of_possible=%d\n", total, accepted, robots * (robots - 1));
  std::printf("pairs_correct=%d pairs_unchecked=%d pairs_relayed=%d\n", correct, unchecked, relayed);
  if (!delays.empty())
    std::printf("first_map_to_accept_s median=%.1f max=%.1f\n", delays[delays.size() / 2], delays.back());
  return 0;
}
