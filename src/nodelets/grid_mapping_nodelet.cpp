// mrslam/GridMappingNodelet: the robot's occupancy grid (slam::GridMapper, MRPT log-odds),
// built from the scans at the filtered poses the localization publishes.
//
// Subscribes (robot namespace): scan and pose (the localization's filtered pose, stamped with
// the scan it was computed from), paired by exact stamp; the laser's mounting on base_frame
// comes from tf. Pairing by stamp rather than looking map -> laser up in tf inserts each scan
// at exactly its filtered pose: tf would interpolate map -> odom between the corrections of two
// scans, and its cache pruning once made a scan fail outright.
// Publishes: map (nav_msgs/OccupancyGrid, latched, at most map_publish_rate Hz and only when it
// changed) and map_metadata.
//
// Zero copy: every publication is a freshly allocated grid filled in place from the MRPT map
// and published as a shared pointer that is never touched again, so nodelets in the same
// manager (the map-share and map-merge nodelets) receive that very object.
#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <message_filters/subscriber.h>
#include <message_filters/time_synchronizer.h>
#include <nav_msgs/MapMetaData.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <deque>
#include <memory>
#include <mutex>

#include "mrslam/slam/grid_mapper.h"
#include "ros_conversions.h"
#include "ros_params.h"

namespace mrslam::nodelets {

class GridMappingNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    pnh.param<std::string>("map_frame", map_frame_, "map");
    pnh.param<std::string>("base_frame", base_frame_, "base_link");
    double rate = 1.0, max_time_jump = 1.0;
    pnh.param("map_publish_rate", rate, rate);
    pnh.param("max_time_jump", max_time_jump_, max_time_jump);
    params_ = robotSlamParamsFrom(pnh);
    if (!(params_.grid.resolution > 0)) {
      NODELET_ERROR("map_resolution must be > 0 (got %f): using 0.05", params_.grid.resolution);
      params_.grid.resolution = 0.05;
    }
    mapper_ = std::make_unique<slam::GridMapper>(params_.grid, Pose2D{});

    tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, nh);
    map_pub_ = nh.advertise<nav_msgs::OccupancyGrid>("map", 1, true);
    metadata_pub_ = nh.advertise<nav_msgs::MapMetaData>("map_metadata", 1, true);
    scan_sub_.subscribe(nh, "scan", 20);
    pose_sub_.subscribe(nh, "pose", 20);
    sync_ = std::make_unique<message_filters::TimeSynchronizer<sensor_msgs::LaserScan, geometry_msgs::PoseWithCovarianceStamped>>(
        scan_sub_, pose_sub_, 50);
    sync_->registerCallback(&GridMappingNodelet::onScan, this);
    publish_timer_ = nh.createTimer(ros::Duration(1.0 / std::max(0.01, rate)), &GridMappingNodelet::onTimer, this);

    diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
    diagnostics_->setHardwareID(nh.getNamespace());
    diagnostics_->add("grid mapping", this, &GridMappingNodelet::diagnose);
    diagnostics_timer_ = nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { diagnostics_->force_update(); });
  }

  void onScan(const sensor_msgs::LaserScan::ConstPtr& msg, const geometry_msgs::PoseWithCovarianceStamped::ConstPtr& pose) {
    std::lock_guard<std::mutex> lock(mutex_);
    const double t = msg->header.stamp.toSec();
    if (last_scan_time_ > 0 && t < last_scan_time_ - max_time_jump_) {
      NODELET_WARN("time went back %.1f s (bag restarted?): starting a new map", last_scan_time_ - t);
      mapper_->clear();
      tf_buffer_->clear();
    }
    last_scan_time_ = t;
    std::string error;
    // The laser is bolted on: its newest mounting transform will do (no waiting for tf at the stamp).
    const auto laser_in_base = lookupPose2D(*tf_buffer_, base_frame_, msg->header.frame_id, ros::Time(0), &error);
    const Pose2D base_in_map = poseFromMsg(pose->pose.pose);
    if (!laser_in_base || !finite(base_in_map)) {
      ++dropped_;
      NODELET_WARN_THROTTLE(10.0, "scan dropped: %s", laser_in_base ? "pose is not finite" : error.c_str());
      return;
    }
    const Pose2D laser_in_map = base_in_map.compose(*laser_in_base);
    const slam::LaserScan scan = scanFromMsg(*msg);
    std::string problem = scanMsgProblem(*msg);
    if (problem.empty()) problem = slam::scanProblem(scan);
    if (!problem.empty()) {
      ++dropped_;
      NODELET_WARN_THROTTLE(10.0, "scan not inserted: %s", problem.c_str());
      return;
    }
    // The mapper's laser offset is zero: tf already gives the laser's own pose.
    mapper_->insert(scan, laser_in_map);
    ++inserted_;
  }

  void onTimer(const ros::TimerEvent&) {
    nav_msgs::OccupancyGridPtr grid;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (inserted_ == 0 || mapper_->version() == published_version_) return;
      published_version_ = mapper_->version();
      const slam::GridGeometry g = mapper_->geometry();
      grid = boost::make_shared<nav_msgs::OccupancyGrid>();
      grid->header.stamp = ros::Time(last_scan_time_);
      grid->header.frame_id = map_frame_;
      grid->info.map_load_time = grid->header.stamp;
      grid->info.resolution = static_cast<float>(g.resolution);
      grid->info.width = static_cast<uint32_t>(g.width);
      grid->info.height = static_cast<uint32_t>(g.height);
      grid->info.origin.position.x = g.origin.x;
      grid->info.origin.position.y = g.origin.y;
      grid->info.origin.orientation.w = 1.0;
      grid->data.resize(static_cast<size_t>(g.width) * g.height);
      mapper_->exportCells(grid->data.data());
    }
    metadata_pub_.publish(grid->info);
    map_pub_.publish(nav_msgs::OccupancyGridConstPtr(grid));  // never modified after this line
    std::lock_guard<std::mutex> lock(mutex_);
    ++published_;
    recent_addresses_.push_back(reinterpret_cast<uintptr_t>(grid.get()));
    if (recent_addresses_.size() > 20) recent_addresses_.pop_front();
  }

  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (inserted_ == 0) status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no scan inserted yet");
    else status.summary(diagnostic_msgs::DiagnosticStatus::OK, "mapping");
    const slam::GridGeometry g = mapper_->geometry();
    status.add("scans inserted", inserted_);
    status.add("scans dropped", dropped_);
    status.add("maps published", published_);
    status.add("width", g.width);
    status.add("height", g.height);
    // For the zero-copy test: subscribers in this manager must receive this very object.
    std::string addresses;
    for (uintptr_t a : recent_addresses_) addresses += std::to_string(a) + " ";
    status.add("recent map addresses", addresses);
  }

  std::mutex mutex_;
  std::string map_frame_, base_frame_;
  double max_time_jump_ = 1.0, last_scan_time_ = 0;
  slam::RobotSlamParams params_;
  std::unique_ptr<slam::GridMapper> mapper_;
  uint64_t published_version_ = 0;
  size_t inserted_ = 0, dropped_ = 0, published_ = 0;
  std::deque<uintptr_t> recent_addresses_;  // of the last 20 grids published
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  message_filters::Subscriber<sensor_msgs::LaserScan> scan_sub_;
  message_filters::Subscriber<geometry_msgs::PoseWithCovarianceStamped> pose_sub_;
  std::unique_ptr<message_filters::TimeSynchronizer<sensor_msgs::LaserScan, geometry_msgs::PoseWithCovarianceStamped>> sync_;
  ros::Publisher map_pub_, metadata_pub_;
  ros::Timer publish_timer_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
  ros::WallTimer diagnostics_timer_;
};

}  // namespace mrslam::nodelets

PLUGINLIB_EXPORT_CLASS(mrslam::nodelets::GridMappingNodelet, nodelet::Nodelet)
