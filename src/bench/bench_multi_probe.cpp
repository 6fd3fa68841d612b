// mrslam_bench_multi_probe N SECONDS: watches a running multi-robot stack (robot1..robotN) for
// SECONDS of wall time and prints, as key=value lines: the simulated time that passed (so the
// real-time factor achieved), the poses each robot published, how many robot pairs are merged,
// and for each merged pair the simulated time from the peer's first map to the accepted transform.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>

#include <algorithm>
#include <map>
#include <mutex>
#include <vector>

int main(int argc, char** argv) {
  ros::init(argc, argv, "mrslam_bench_multi_probe", ros::init_options::AnonymousName);
  if (argc < 3) {
    std::fprintf(stderr, "usage: mrslam_bench_multi_probe N SECONDS\n");
    return 2;
  }
  const int robots = std::atoi(argv[1]);
  const double seconds = std::atof(argv[2]);
  ros::NodeHandle nh;
  std::mutex mutex;
  std::map<int, size_t> poses;
  std::map<std::pair<int, std::string>, std::pair<bool, double>> pairs;  // accepted, delay
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
        r + "/pose", 100, [&, k](const geometry_msgs::PoseWithCovarianceStamped::ConstPtr&) {
          std::lock_guard<std::mutex> lock(mutex);
          ++poses[k];
        }));
    subs.push_back(nh.subscribe<diagnostic_msgs::DiagnosticArray>(
        r + "/merge_status", 10, [&, k](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
          std::lock_guard<std::mutex> lock(mutex);
          for (const auto& s : m->status) {
            std::map<std::string, std::string> v;
            for (const auto& kv : s.values) v[kv.key] = kv.value;
            const bool accepted = v["accepted"] == "True";
            pairs[{k, s.name}] = {accepted, accepted ? std::stod(v["accepted_since"]) - std::stod(v["first_map_time"]) : -1};
          }
        }));
  }
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const ros::WallTime start = ros::WallTime::now();
  ros::WallDuration(seconds).sleep();
  const double wall = (ros::WallTime::now() - start).toSec();
  std::lock_guard<std::mutex> lock(mutex);
  // The real-time factor over the time the clock was running (the bag playing).
  const double played_wall = first_clock >= 0 ? (last_wall - first_wall).toSec() : 0.0;
  std::printf("wall_s=%.1f sim_s=%.1f played_wall_s=%.1f\n", wall,
              last_clock > first_clock ? last_clock - first_clock : 0.0, played_wall);
  for (int k = 1; k <= robots; ++k) std::printf("poses_robot%d=%zu\n", k, poses[k]);
  int accepted = 0, total = 0;
  std::vector<double> delays;
  for (const auto& [key, value] : pairs) {
    if (key.second.rfind("robot", 0) != 0) continue;
    ++total;
    if (value.first) ++accepted, delays.push_back(value.second);
  }
  std::sort(delays.begin(), delays.end());
  std::printf("pairs_seen=%d pairs_accepted=%d of_possible=%d\n", total, accepted, robots * (robots - 1));
  if (!delays.empty())
    std::printf("first_map_to_accept_s median=%.1f max=%.1f\n", delays[delays.size() / 2], delays.back());
  return 0;
}
