// mrslam_bench_handoff: latency of handing one 4000 x 4000 OccupancyGrid (16 MB) from a
// publisher to a subscriber, (a) inside one process as nodelets do (the subscriber receives
// the published shared pointer) and (b) between two processes (serialized over TCPROS).
//   mrslam_bench_handoff --intra [ROUNDS]        one process: publisher and subscriber
//   mrslam_bench_handoff --sub ROUNDS &          second process: subscriber
//   mrslam_bench_handoff --pub ROUNDS            first process: publisher (after --sub is up)
// The stamp in the header is the wall time of publication; the subscriber prints the median
// and the maximum latency in milliseconds.
#include <nav_msgs/OccupancyGrid.h>
#include <ros/ros.h>

#include <algorithm>
#include <mutex>
#include <vector>

namespace {

constexpr int kSide = 4000;

nav_msgs::OccupancyGridPtr bigGrid() {
  auto g = boost::make_shared<nav_msgs::OccupancyGrid>();
  g->info.width = g->info.height = kSide;
  g->info.resolution = 0.05f;
  g->data.assign(static_cast<size_t>(kSide) * kSide, -1);
  return g;
}

void report(std::vector<double> ms, const char* what, bool same_object) {
  std::sort(ms.begin(), ms.end());
  std::printf("%s: %zu grids of %dx%d, latency median %.3f ms, max %.3f ms%s\n", what, ms.size(), kSide, kSide,
              ms[ms.size() / 2], ms.back(), same_object ? " (same object received: zero copy)" : "");
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "mrslam_bench_handoff", ros::init_options::AnonymousName);
  const std::string mode = argc > 1 ? argv[1] : "--intra";
  const int rounds = argc > 2 ? std::max(1, std::atoi(argv[2])) : 20;
  ros::NodeHandle nh;
  std::mutex mutex;
  std::vector<double> latencies;
  bool same_object = true;
  const void* last_published = nullptr;
  auto on_grid = [&](const nav_msgs::OccupancyGrid::ConstPtr& g) {
    const double ms = (ros::WallTime::now().toSec() - g->header.stamp.toSec()) * 1e3;
    std::lock_guard<std::mutex> lock(mutex);
    latencies.push_back(ms);
    if (mode == "--intra") same_object = same_object && g.get() == last_published;
  };
  if (mode == "--intra" || mode == "--sub") {
    ros::Subscriber sub = nh.subscribe<nav_msgs::OccupancyGrid>("/mrslam_bench/grid", 2, on_grid);
    ros::Publisher pub;
    if (mode == "--intra") pub = nh.advertise<nav_msgs::OccupancyGrid>("/mrslam_bench/grid", 2);
    ros::AsyncSpinner spinner(1);
    spinner.start();
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(120);
    for (int i = 0; ros::ok() && ros::WallTime::now() < deadline; ++i) {
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (static_cast<int>(latencies.size()) >= rounds) break;
      }
      if (mode == "--intra") {
        auto g = bigGrid();
        g->header.stamp.fromSec(ros::WallTime::now().toSec());
        {
          std::lock_guard<std::mutex> lock(mutex);
          last_published = g.get();
        }
        pub.publish(nav_msgs::OccupancyGrid::ConstPtr(g));
      }
      ros::WallDuration(0.2).sleep();
    }
    std::lock_guard<std::mutex> lock(mutex);
    if (latencies.empty()) {
      std::fprintf(stderr, "mrslam_bench_handoff: no grid received\n");
      return 1;
    }
    report(latencies, mode == "--intra" ? "one process (nodelet pointer pass)" : "two processes (serialized)",
           mode == "--intra" && same_object);
    return 0;
  }
  ros::Publisher pub = nh.advertise<nav_msgs::OccupancyGrid>("/mrslam_bench/grid", 2);
  while (ros::ok() && pub.getNumSubscribers() == 0) ros::WallDuration(0.05).sleep();
  ros::WallDuration(0.5).sleep();
  for (int i = 0; i < rounds + 5 && ros::ok(); ++i) {
    auto g = bigGrid();
    g->header.stamp.fromSec(ros::WallTime::now().toSec());
    pub.publish(nav_msgs::OccupancyGrid::ConstPtr(g));
    ros::WallDuration(0.5).sleep();
  }
  return 0;
}
