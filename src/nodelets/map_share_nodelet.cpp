// mrslam/MapShareNodelet: shares this robot's map with its peers as LocalMapShare on a shared
// topic (default /mrslam/map_share), at most share_rate Hz and only when the map changed.
// The grid is the very object the mapping nodelet published (received by pointer in the same
// manager) and goes out inside mrslam::SharedMap without a copy.
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>

#include <mutex>

#include "mrslam/ros/shared_map.h"

namespace mrslam::nodelets {

class MapShareNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::string topic;
    double rate = 0.5;
    pnh.param<std::string>("robot_id", robot_id_, "robot1");
    pnh.param<std::string>("share_topic", topic, "/mrslam/map_share");
    pnh.param("share_rate", rate, rate);
    share_pub_ = nh.advertise<SharedMap>(topic, 10);
    map_sub_ = nh.subscribe("map", 1, &MapShareNodelet::onMap, this);
    pose_sub_ = nh.subscribe("pose", 1, &MapShareNodelet::onPose, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / std::max(0.01, rate)), &MapShareNodelet::onTimer, this);
  }

  void onMap(const nav_msgs::OccupancyGrid::ConstPtr& map) {
    std::lock_guard<std::mutex> lock(mutex_);
    latest_map_ = map;
  }
  void onPose(const geometry_msgs::PoseWithCovarianceStamped::ConstPtr& pose) {
    std::lock_guard<std::mutex> lock(mutex_);
    pose_ = pose->pose;
  }

  void onTimer(const ros::TimerEvent&) {
    auto share = boost::make_shared<SharedMap>();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!latest_map_ || latest_map_ == shared_map_) return;  // nothing new to share
      shared_map_ = latest_map_;
      share->header = latest_map_->header;
      share->robot_id = robot_id_;
      share->map = latest_map_;  // the pointer, not a copy
      share->pose = pose_;
      share->version = ++version_;
    }
    share_pub_.publish(SharedMap::ConstPtr(share));
  }

  std::mutex mutex_;  // guards latest_map_, shared_map_, pose_ and version_ (callbacks and timer)
  std::string robot_id_;
  nav_msgs::OccupancyGrid::ConstPtr latest_map_, shared_map_;
  geometry_msgs::PoseWithCovariance pose_;
  uint32_t version_ = 0;
  ros::Publisher share_pub_;
  ros::Subscriber map_sub_, pose_sub_;
  ros::Timer timer_;
};

}  // namespace mrslam::nodelets

PLUGINLIB_EXPORT_CLASS(mrslam::nodelets::MapShareNodelet, nodelet::Nodelet)
