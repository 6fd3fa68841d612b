// mrslam/MapShareNodelet: shares this robot's map with its peers, at most share_rate Hz and
// only when the map changed, in one of two encodings (share_encoding):
//   - "zlib" (default): CompressedMapShare on compressed_share_topic (/mrslam/map_share_z), the
//     grid's cells compressed losslessly (cell_codec.h): what crosses the link between robots;
//   - "none": LocalMapShare on share_topic (/mrslam/map_share) with the grid as is: the very
//     object the mapping nodelet published (received by pointer in the same manager), inside
//     mrslam::SharedMap without a copy.
// Every MapMergeNodelet takes both. A map unchanged for share_keyframe_period (wall clock) is
// sent again with the same version: peers that missed it (a lossy link) get it, and peers can
// tell a robot whose map did not change from one whose link is down. A subscriber that connects
// (a late joiner, or a merger re-making its subscriptions after an outage) is sent the last
// share at once, to it alone, instead of waiting up to a keyframe period for the next one.
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <mrslam/CompressedMapShare.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>

#include <mutex>

#include "mrslam/cell_codec.h"
#include "mrslam/ros/shared_map.h"
#include "ros_params.h"

namespace mrslam::nodelets {

class MapShareNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    const PrivateParams config(pnh);  // one call to the master for every key
    std::string topic, compressed_topic, encoding;
    double rate = 0.5;
    config.param<std::string>("robot_id", robot_id_, "robot1");
    config.param<std::string>("share_topic", topic, "/mrslam/map_share");
    config.param<std::string>("compressed_share_topic", compressed_topic, "/mrslam/map_share_z");
    config.param<std::string>("share_encoding", encoding, "zlib");
    config.param("share_compression_level", compression_level_, 1);
    config.param("share_rate", rate, rate);
    config.param("share_keyframe_period", keyframe_period_, 30.0);
    if (encoding != "zlib" && encoding != "none") {
      NODELET_ERROR("share_encoding '%s' is neither \"zlib\" nor \"none\": using \"zlib\"", encoding.c_str());
      encoding = "zlib";
    }
    compress_ = encoding == "zlib";
    compression_level_ = std::clamp(compression_level_, 1, 9);
    // Every share is the whole map, so a peer needs only the newest: a queue of one per peer.
    // A longer queue fills while a link is down and, when it returns, sends every stale map
    // ahead of the newest over a slow link (1 Mbit/s shared with the robot's other traffic).
    const ros::SubscriberStatusCallback greet = [this](const ros::SingleSubscriberPublisher& subscriber) {
      onSubscriberConnect(subscriber);
    };
    if (compress_)
      share_pub_ = nh.advertise<CompressedMapShare>(compressed_topic, 1, greet);
    else
      share_pub_ = nh.advertise<SharedMap>(topic, 1, greet);
    map_sub_ = nh.subscribe("map", 1, &MapShareNodelet::onMap, this);
    pose_sub_ = nh.subscribe("pose", 1, &MapShareNodelet::onPose, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / std::max(0.01, rate)), &MapShareNodelet::onTimer, this);
    if (keyframe_period_ > 0)
      keyframe_timer_ = nh.createWallTimer(ros::WallDuration(keyframe_period_ / 4), &MapShareNodelet::onKeyframeTimer, this);
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
    send(share);
  }

  // A new subscriber gets the last share sent (the newest: send_mutex_ orders it after every
  // share already sent, so a peer never receives an older version after a newer one). Without
  // it, a merger whose link came back after an outage heard an unchanged map only at the next
  // keyframe, up to share_keyframe_period (30 s) after it had reconnected.
  void onSubscriberConnect(const ros::SingleSubscriberPublisher& subscriber) {
    std::lock_guard<std::mutex> send_lock(send_mutex_);
    if (!last_sent_) return;
    if (compress_)
      subscriber.publish(*last_compressed_);
    else
      subscriber.publish(*last_sent_);
  }

  void onKeyframeTimer(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> send_lock(send_mutex_);
    if (!last_sent_ || (ros::WallTime::now() - last_sent_time_).toSec() < keyframe_period_) return;
    sendLocked(last_sent_);
  }

  void send(const SharedMap::ConstPtr& share) {
    std::lock_guard<std::mutex> send_lock(send_mutex_);
    sendLocked(share);
  }

  // send_mutex_ held: shares leave in version order (a keyframe never overtakes a newer map,
  // which a peer would take for a restart).
  void sendLocked(const SharedMap::ConstPtr& share) {
    if (compress_) {
      if (share != last_sent_ || !last_compressed_) last_compressed_ = compressed(*share);  // a keyframe reuses it
      share_pub_.publish(last_compressed_);
    } else {
      share_pub_.publish(share);
    }
    last_sent_ = share;
    last_sent_time_ = ros::WallTime::now();
  }

  CompressedMapShare::ConstPtr compressed(const SharedMap& share) const {
    auto out = boost::make_shared<CompressedMapShare>();
    out->header = share.header;
    out->robot_id = share.robot_id;
    out->map_header = share.map->header;
    out->info = share.map->info;
    out->encoding = "zlib";
    out->cells = compressCells(share.map->data.data(), share.map->data.size(), compression_level_);
    out->pose = share.pose;
    out->version = share.version;
    return out;
  }

  std::mutex mutex_;  // guards latest_map_, shared_map_, pose_ and version_ (callbacks and the share timer)
  std::mutex send_mutex_;  // orders sending; guards last_sent_, last_compressed_ and last_sent_time_
                           // (both timers and the connect callback)
  std::string robot_id_;
  bool compress_ = true;
  int compression_level_ = 1;
  nav_msgs::OccupancyGrid::ConstPtr latest_map_, shared_map_;
  geometry_msgs::PoseWithCovariance pose_;
  uint32_t version_ = 0;
  ros::Publisher share_pub_;
  ros::Subscriber map_sub_, pose_sub_;
  ros::Timer timer_;
  ros::WallTimer keyframe_timer_;
  double keyframe_period_ = 30.0;  // s, wall clock; 0: never re-sent
  SharedMap::ConstPtr last_sent_;
  CompressedMapShare::ConstPtr last_compressed_;  // last_sent_ as it went out (compress_ only)
  ros::WallTime last_sent_time_;
};

}  // namespace mrslam::nodelets

PLUGINLIB_EXPORT_CLASS(mrslam::nodelets::MapShareNodelet, nodelet::Nodelet)
