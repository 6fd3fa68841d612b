// A tf listener like tf2_ros::TransformListener (every transform on /tf and /tf_static goes
// into the buffer, its publisher as the authority, from a thread of its own) except for one
// transform, the robot's odometry (odom_frame -> base_frame): that one is taken only from the
// node that published it first, while that node keeps publishing (PublisherClaim). A second
// node's odometry would move the robot, and no scan can tell a forged jump from a real one.
#pragma once

#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>

#include <atomic>
#include <mutex>
#include <string>
#include <thread>

#include "mrslam/publisher_claim.h"
#include "ros_conversions.h"

namespace mrslam::nodelets {

class GuardedTransformListener {
 public:
  GuardedTransformListener(tf2_ros::Buffer& buffer, const std::string& odom_frame, const std::string& base_frame,
                           double owner_timeout)
      : buffer_(buffer), odom_frame_(bareFrame(odom_frame)), base_frame_(bareFrame(base_frame)), timeout_(owner_timeout) {
    nh_.setCallbackQueue(&queue_);
    tf_sub_ = nh_.subscribe("/tf", 100, &GuardedTransformListener::onTf, this, ros::TransportHints().tcpNoDelay());
    static_sub_ = nh_.subscribe("/tf_static", 100, &GuardedTransformListener::onStaticTf, this);
    thread_ = std::thread([this] {
      while (!stop_ && nh_.ok()) queue_.callAvailable(ros::WallDuration(0.01));
    });
  }
  ~GuardedTransformListener() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }

  struct Refusals {
    size_t transforms = 0;  // odometry transforms refused from a second publisher
    std::string publisher, holder;  // the last refused publisher and the odometry's holder
  };
  Refusals refusals() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return refusals_;
  }

 private:
  void onTf(const ros::MessageEvent<tf2_msgs::TFMessage const>& event) { insert(event, false); }
  void onStaticTf(const ros::MessageEvent<tf2_msgs::TFMessage const>& event) { insert(event, true); }

  void insert(const ros::MessageEvent<tf2_msgs::TFMessage const>& event, bool is_static) {
    const std::string& publisher = event.getPublisherName();
    const double now = ros::WallTime::now().toSec();
    for (const geometry_msgs::TransformStamped& t : event.getMessage()->transforms) {
      if (!is_static && bareFrame(t.header.frame_id) == odom_frame_ && bareFrame(t.child_frame_id) == base_frame_ && !odometryFrom(publisher, now))
        continue;
      try {
        buffer_.setTransform(t, publisher, is_static);
      } catch (const tf2::TransformException& e) {
        ROS_WARN_THROTTLE(5.0, "tf from %s refused: %s", publisher.c_str(), e.what());
      }
    }
  }

  bool odometryFrom(const std::string& publisher, double now) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (odometry_owner_.heldByAnother(publisher, now, timeout_)) {
      ++refusals_.transforms;
      refusals_.publisher = publisher;
      ROS_ERROR_THROTTLE(5.0, "odometry %s -> %s from %s refused: it belongs to %s", odom_frame_.c_str(),
                         base_frame_.c_str(), printable(publisher).c_str(), printable(odometry_owner_.holder()).c_str());
      return false;
    }
    odometry_owner_.take(publisher, now);
    refusals_.holder = publisher;
    return true;
  }

  tf2_ros::Buffer& buffer_;
  const std::string odom_frame_, base_frame_;
  const double timeout_;
  mutable std::mutex mutex_;  // guards odometry_owner_ and refusals_ (tf thread, diagnostics)
  PublisherClaim odometry_owner_;
  Refusals refusals_;
  ros::NodeHandle nh_;
  ros::CallbackQueue queue_;
  ros::Subscriber tf_sub_, static_sub_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace mrslam::nodelets
