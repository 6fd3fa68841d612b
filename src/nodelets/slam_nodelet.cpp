// mrslam/SlamNodelet: one robot's SLAM as a thin layer over slam::FrontEnd (front_end.h): the
// pose graph with loop closure by default, or the paper's cascaded EKF alone (loop_closure:
// false). It owns the robot's only map.
//
// Subscribes (robot namespace): scan (sensor_msgs/LaserScan), odom (nav_msgs/Odometry, watched
// for NaN), imu (sensor_msgs/Imu, optional). Publishes: tf map_frame -> odom_frame (REP-105:
// map -> base is the estimated pose; with use_odometry false, a laser-only robot or bag, there
// is no odometry frame and it publishes map_frame -> base_frame itself), pose
// (geometry_msgs/PoseWithCovarianceStamped), odometry/filtered (nav_msgs/Odometry in
// map_frame), trajectory (nav_msgs/Path, latched: the current estimate of every scan's pose,
// which moves when a loop closes), map
// (nav_msgs/OccupancyGrid, latched, at most map_publish_rate Hz and only when its content
// changed) and map_metadata, diagnostics. Service ~finish_run (std_srvs/Trigger): the run is
// over (before saving the map, as Cartographer's finish_trajectory): the last submap is searched
// for loop closures, every node is refined against all the others (GraphSlam::finish(),
// pose_refinement.h) and the map and trajectory are published again. A scan after it goes on
// from there, in a new submap.
//
// Mountings come from tf's full rotation (slam/sensor_mount.h): a laser upside down has its
// scans read as an upright one would list them, one tilted beyond kMaxLaserTiltDeg is refused,
// and a gyro's angular velocity is turned into base_frame, whichever way up it sits.
//
// Inputs belong to their publisher: scans from a second node on the scan topic, and odometry
// transforms from a second node, are refused and counted (input_owner_timeout).
//
// Timing: callbacks of different topics run in any order, so nothing is accumulated as it
// arrives. With odometry, each scan waits (tf2 message filter) until odom_frame -> base_frame
// is known at its stamp; then, while a gyro is publishing, until its samples reach that stamp
// (at most imu_wait, after which it goes on without the gyro; a loaded host delivers the gyro
// behind the scans); the odometry increment is taken from tf at the two scan stamps and the
// gyro samples are integrated over exactly that interval from a time-ordered buffer
// (slam/gyro_buffer.h).
//
// Zero copy: every map is a freshly allocated grid composed from the front end's map pieces
// outside the lock the scan callback needs, published as a shared pointer and never touched
// again, so nodelets in the same manager (map share, map merge) receive that very object.
#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <nav_msgs/MapMetaData.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/LaserScan.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/message_filter.h>
#include <tf2_ros/transform_broadcaster.h>

#include <atomic>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>

#include "mrslam/publisher_claim.h"
#include "mrslam/scan_stamp_gate.h"
#include "mrslam/slam/front_end.h"
#include "mrslam/slam/gyro_buffer.h"
#include "mrslam/slam/map_composer.h"
#include "mrslam/slam/sensor_mount.h"
#include "mrslam/slam/simulated_gyro.h"
#include "guarded_tf_listener.h"
#include "ros_conversions.h"
#include "ros_params.h"

namespace mrslam::nodelets {

class SlamNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    const PrivateParams config(pnh);  // one call to the master for every key
    config.param<std::string>("map_frame", map_frame_, "map");
    config.param<std::string>("odom_frame", odom_frame_, "odom");
    config.param<std::string>("base_frame", base_frame_, "base_link");
    config.param("publish_tf", publish_tf_, true);
    config.param("use_odometry", use_odometry_, true);
    config.param("transform_tolerance", transform_tolerance_, 0.1);
    ScanStampRules stamp_rules;
    config.param("max_time_jump", stamp_rules.max_time_jump, stamp_rules.max_time_jump);
    config.param("restart_scans", stamp_rules.restart_scans, stamp_rules.restart_scans);
    config.param("future_tolerance", stamp_rules.future_tolerance, stamp_rules.future_tolerance);
    stamp_gate_ = std::make_unique<ScanStampGate>(stamp_rules);
    config.param("max_rays", max_rays_, 10000);
    config.param("trajectory_max_poses", trajectory_max_poses_, 20000);
    config.param("input_owner_timeout", input_owner_timeout_, 5.0);
    config.param("gyro_noise_density", gyro_model_.noise_density, gyro_model_.noise_density);
    config.param("gyro_residual_bias", gyro_model_.residual_bias, gyro_model_.residual_bias);
    double imu_max_gap = 0.1;
    config.param("imu_wait", imu_wait_, imu_wait_);
    config.param("imu_max_gap", imu_max_gap, imu_max_gap);
    if (!(imu_wait_ >= 0) || !(imu_max_gap > 0)) {
      NODELET_ERROR("imu_wait must be >= 0 and imu_max_gap > 0 (got %f, %f): using 0.5 and 0.1", imu_wait_, imu_max_gap);
      imu_wait_ = 0.5, imu_max_gap = 0.1;
    }
    gyro_ = slam::GyroBuffer(imu_max_gap);
    double map_rate = 1.0, period = 1.0;
    config.param("map_publish_rate", map_rate, map_rate);
    config.param("diagnostics_period", period, period);
    params_ = robotSlamParamsFrom(config);
    const std::string params_problem = slam::robotSlamParamsProblem(params_);
    if (!params_problem.empty()) {
      // The robot keeps mapping, on the documented defaults (config/robot.yaml's, which the
      // code shares), and says so for as long as it runs.
      params_problem_ = "SLAM parameters refused (" + params_problem + "): running on config/robot.yaml's defaults";
      NODELET_ERROR("%s", params_problem_.c_str());
      params_ = slam::RobotSlamParams{};
    }

    tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
    tf_listener_ = std::make_unique<GuardedTransformListener>(*tf_buffer_, odom_frame_, base_frame_, input_owner_timeout_);
    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
    pose_pub_ = nh.advertise<geometry_msgs::PoseWithCovarianceStamped>("pose", 10);
    odom_pub_ = nh.advertise<nav_msgs::Odometry>("odometry/filtered", 10);
    path_pub_ = nh.advertise<nav_msgs::Path>("trajectory", 1, true);
    map_pub_ = nh.advertise<nav_msgs::OccupancyGrid>("map", 1, true);
    metadata_pub_ = nh.advertise<nav_msgs::MapMetaData>("map_metadata", 1, true);
    if (use_odometry_) odom_sub_ = nh.subscribe("odom", 100, &SlamNodelet::onOdometry, this);
    // 2 s of a 1 kHz gyro: a sample lost to a full queue leaves a gap, and the scan around it
    // goes without the gyro.
    imu_sub_ = nh.subscribe("imu", 2000, &SlamNodelet::onImu, this);
    // Scans reach the tf filter only past the checks that need no transform. In the filter's
    // queue a scan that can never be transformed (stamped far ahead) waits until 50 newer ones
    // push it out, holding its memory: 60 scans of 2M rays stamped ahead took a manager from
    // 108 to 522 MB before these checks came first (132 MB after).
    scan_sub_ = nh.subscribe("scan", 20, &SlamNodelet::onRawScan, this);
    if (use_odometry_) startOdometryFilter(nh);  // without odometry, scans wait for no transform
    startTimers(nh, pnh, map_rate, period);
    finish_srv_ = pnh.advertiseService("finish_run", &SlamNodelet::onFinishRun, this);
  }

  // Under the lock the scan callback takes: scans that arrive meanwhile wait (the refinement
  // takes about a second per 1000 nodes of graph on one core).
  bool onFinishRun(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!robot_) {
      response.success = false;
      response.message = "no scan has been used yet: nothing to finish";
      return true;
    }
    robot_->finish();
    const slam::FrontEndStats stats = robot_->stats();
    response.success = true;
    response.message = "run finished: " + std::to_string(stats.nodes_refined) + " of " + std::to_string(stats.nodes) +
                       " nodes refined (" + std::to_string(stats.nodes_reseated) +
                       " after a correlative search; " + std::to_string(stats.stretches_reanchored) +
                       " stretches turned back); the map and trajectory follow within 1/map_publish_rate s";
    return true;
  }

  // Scans wait here until odom_frame -> base_frame is known at their stamps.
  void startOdometryFilter(ros::NodeHandle& nh) {
    scan_filter_ = std::make_unique<tf2_ros::MessageFilter<sensor_msgs::LaserScan>>(*tf_buffer_, odom_frame_, 50, nh);
    scan_filter_->registerCallback(&SlamNodelet::onTransformedScan, this);
    scan_filter_->registerFailureCallback(
        [this](const sensor_msgs::LaserScan::ConstPtr& msg, tf2_ros::filter_failure_reasons::FilterFailureReason reason) {
          std::lock_guard<std::mutex> lock(mutex_);
          ++rejected_;
          last_problem_ = "no odometry transform at a scan's stamp";
          const char* why = reason == tf2_ros::filter_failure_reasons::OutTheBack     ? "stamped before the transforms kept"
                            : reason == tf2_ros::filter_failure_reasons::EmptyFrameID ? "no frame_id"
                                                                                      : "the queue overflowed waiting";
          NODELET_WARN_THROTTLE(5.0, "scan dropped: no transform %s -> %s at its stamp (%s)", odom_frame_.c_str(),
                                msg->header.frame_id.c_str(), why);
        });
  }

  void startTimers(ros::NodeHandle& nh, ros::NodeHandle& pnh, double map_rate, double period) {
    map_timer_ = nh.createWallTimer(ros::WallDuration(1.0 / std::max(0.01, map_rate)), &SlamNodelet::onMapTimer, this);
    gyro_wait_timer_ = nh.createWallTimer(ros::WallDuration(kGyroWaitTick), [this](const ros::WallTimerEvent&) { drainScans(); });

    diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
    diagnostics_->setHardwareID(nh.getNamespace());
    diagnostics_->add("slam", this, &SlamNodelet::diagnose);
    diagnostics_timer_ = nh.createWallTimer(ros::WallDuration(std::max(0.1, period)),
                                            [this](const ros::WallTimerEvent&) { diagnostics_->force_update(); });
  }

  void onOdometry(const nav_msgs::Odometry::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(input_mutex_);
    if (!finite(poseFromMsg(msg->pose.pose))) {
      ++bad_odometry_;
      NODELET_WARN_THROTTLE(5.0, "odometry with a NaN/inf pose");
    }
    ++odometry_messages_;
  }

  void onImu(const sensor_msgs::Imu::ConstPtr& msg) {
    {
      std::lock_guard<std::mutex> lock(input_mutex_);
      // Kept in time order until a scan integrates the interval it belongs to.
      // sensor_msgs/Imu: element 0 of a covariance at -1 says the IMU gives no such estimate.
      // Zeros read as a yaw rate would say the robot never turns.
      if (msg->angular_velocity_covariance[0] == -1) {
        NODELET_ERROR_THROTTLE(5.0, "IMU samples on %s carry no angular velocity (angular_velocity_covariance[0] "
                               "is -1): set aside, the SLAM runs without a gyro", imu_sub_.getTopic().c_str());
        ++imu_without_rate_;
        return;
      }
      std::string error;
      const std::optional<double> yaw_rate = yawRateOf(*msg, &error);
      if (!yaw_rate) {
        NODELET_WARN_THROTTLE(5.0, "IMU sample ignored: no tf %s -> %s yet (%s)", base_frame_.c_str(),
                              msg->header.frame_id.c_str(), error.c_str());
        ++imu_rejected_;
        return;
      }
      if (!gyro_.add(msg->header.stamp.toSec(), *yaw_rate)) {
        NODELET_WARN_THROTTLE(5.0, "IMU yaw rate or stamp is NaN/inf: sample ignored");
        ++imu_rejected_;
        return;
      }
      gyro_heard_ = ros::WallTime::now().toSec();
    }
    drainScans();
  }

  // The robot's yaw rate from an IMU sample: its angular velocity turned from the IMU's frame
  // into base_frame through tf (sensor_mount.h); a sample without a frame, or in base_frame, is
  // taken as it is. Nothing while tf does not know the IMU's frame. The mounting is looked up
  // once per frame: an IMU is bolted on.
  std::optional<double> yawRateOf(const sensor_msgs::Imu& msg, std::string* error) {  // input_mutex_ held
    const std::string frame = bareFrame(msg.header.frame_id);
    const Eigen::Vector3d rate(msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z);
    if (frame.empty() || frame == bareFrame(base_frame_)) return rate.z();
    if (!imu_mount_ || imu_mount_->first != frame) {
      const auto imu = lookupTransform(*tf_buffer_, base_frame_, frame, ros::Time(0), error);
      if (!imu) return std::nullopt;
      imu_mount_.emplace(frame, quaternionOf(imu->rotation));
    }
    return slam::baseYawRate(imu_mount_->second, rate);
  }

  // The gyro's yaw change over [t0, t1), when its samples cover the interval; a gyro that is
  // publishing but did not cover it is counted and reported.
  void integrateGyro(double t0, double t1) {  // mutex_ held
    std::lock_guard<std::mutex> lock(input_mutex_);
    const bool publishing = gyroPublishing();
    const std::optional<double> newest = gyro_.newest();
    if (const auto yaw = gyro_.integrate(t0, t1)) {
      robot_->addGyro(*yaw, slam::gyroIncrementVariance(gyro_model_, t1 - t0));
    } else if (publishing) {
      ++scans_without_gyro_;
      last_problem_ = "gyro samples did not cover a scan's interval";
      NODELET_WARN_THROTTLE(5.0, "gyro samples do not cover the scan interval [%.3f, %.3f] (newest sample %.3f s before "
                            "the scan, or a gap over imu_max_gap): this scan's turn comes from odometry and the scan "
                            "alone (a gyro lagging the scans by more than imu_wait on a loaded host does this)",
                            t0, t1, newest ? t1 - *newest : 0.0);
    }
  }

  // A gyro sample arrived within the last second (wall) or the last imu_wait: scans wait for it.
  bool gyroPublishing() const {  // input_mutex_ held
    return params_.use_imu && gyro_heard_ > 0 && ros::WallTime::now().toSec() - gyro_heard_ <= std::max(1.0, imu_wait_);
  }

  // A scan out of the tf filter waits in line for the gyro samples up to its stamp.
  void onTransformedScan(const ros::MessageEvent<sensor_msgs::LaserScan const>& event) {
    {
      std::lock_guard<std::mutex> lock(waiting_mutex_);
      waiting_.push_back({event, ros::WallTime::now().toSec()});
      scans_waiting_ = true;
    }
    drainScans();
  }

  // Processes the waiting scans in order, each once the gyro's samples reach its stamp, the
  // gyro is silent, it has waited imu_wait, or the line is full. One thread drains at a time
  // (order matters); a callback that finds another draining leaves the line to it and to the
  // timer, so no callback (a gyro sample's least of all) waits for a scan's matching.
  void drainScans() {
    if (!scans_waiting_) return;
    std::unique_lock<std::mutex> draining(drain_mutex_, std::try_to_lock);
    if (!draining.owns_lock()) return;
    for (;;) {
      ros::MessageEvent<sensor_msgs::LaserScan const> event;
      {
        std::lock_guard<std::mutex> lock(waiting_mutex_);
        if (waiting_.empty()) {
          scans_waiting_ = false;
          return;
        }
        const WaitingScan& front = waiting_.front();
        const double waited = ros::WallTime::now().toSec() - front.arrived;
        bool wait = false;
        {
          std::lock_guard<std::mutex> input_lock(input_mutex_);
          const std::optional<double> newest = gyro_.newest();
          wait = gyroPublishing() && (!newest || *newest < front.event.getMessage()->header.stamp.toSec()) &&
                 waited < imu_wait_ && waiting_.size() <= kMaxWaitingScans;
        }
        if (wait) return;
        if (waited >= kGyroWaitTick) ++scans_waited_for_gyro_;
        event = front.event;
        waiting_.pop_front();
      }
      onScan(event);
    }
  }

  void onRawScan(const ros::MessageEvent<sensor_msgs::LaserScan const>& event) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!admissible(*event.getMessage(), event.getPublisherName())) return;
      scan_arrivals_[event.getMessage().get()] = ros::WallTime::now().toSec();
      // Scans the tf filter or a later check dropped never come back for theirs: past the cap
      // entries go (any of them; a lag not recorded is harmless).
      while (scan_arrivals_.size() > kMaxScanArrivals) scan_arrivals_.erase(scan_arrivals_.begin());
    }
    if (use_odometry_) scan_filter_->add(event);
    else onTransformedScan(event);
  }

  void onScan(const ros::MessageEvent<sensor_msgs::LaserScan const>& event) {
    try {
      processScan(event.getMessage(), event.getPublisherName());
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++faults_;
      last_problem_ = std::string("scan: ") + e.what();
      NODELET_ERROR_THROTTLE(5.0, "caught: %s", last_problem_.c_str());
    }
  }

  // Why a scan's stamp cannot be used now (empty when it can); starts a new map when the bag
  // restarted (mrslam/scan_stamp_gate.h).
  std::string stampProblem(const ros::Time& stamp) {  // mutex_ held
    const StampVerdict verdict = stamp_gate_->check(stamp.toSec(), ros::Time::now().toSec());
    if (verdict.clock_lag > clock_lag_) clock_lag_ = verdict.clock_lag;
    if (verdict.kind == StampVerdict::Kind::kUse && verdict.clock_lag > stamp_gate_->rules().future_tolerance)
      NODELET_WARN_THROTTLE(30.0, "scans arrive up to %.1f s ahead of the clock (rosbag play publishes no /clock while "
                            "it catches up under load; on wall time, the laser's host clock runs ahead): each scan "
                            "is judged against the last one", verdict.clock_lag);
    if (verdict.kind == StampVerdict::Kind::kRefuse) return verdict.reason;
    if (verdict.kind == StampVerdict::Kind::kUse) return "";
    NODELET_WARN("%s (bag restarted?): starting a new map and trajectory", verdict.reason.c_str());
    robot_.reset();
    last_odom_.reset();
    {
      std::lock_guard<std::mutex> input_lock(input_mutex_);
      gyro_.clear();
    }
    stamps_.clear();
    published_version_ = ~0ull, published_poses_ = 0;
    tf_buffer_->clear();
    ++resets_;
    return "";
  }

  // The checks that change nothing, made before a scan waits for its odometry and again before
  // it is used: a scan they refuse leaves the filter, the stamp rules' count of scans going
  // back and the topic's owner as they were. Refusals are counted here.
  bool admissible(const sensor_msgs::LaserScan& msg, const std::string& publisher) {  // mutex_ held
    std::string problem = scanMsgProblem(msg, static_cast<size_t>(std::max(1, max_rays_)));
    if (problem.empty() && msg.header.stamp.isZero()) problem = "scan stamped 0";
    if (!problem.empty()) {
      ++rejected_;
      last_problem_ = problem;
      NODELET_ERROR_THROTTLE(5.0, "scan rejected: %s", problem.c_str());
      return false;
    }
    // The scan topic belongs to the node that publishes on it (the laser driver, a bag): well-
    // formed scans from a second node would be drawn into the map wherever the odometry says,
    // and the front end cannot tell them from real ones; their stamps must not count towards a
    // restart either (three old stamps in a row would wipe the map).
    if (scan_owner_.heldByAnother(publisher, ros::WallTime::now().toSec(), input_owner_timeout_)) {
      ++rejected_, ++impostor_scans_;
      last_problem_ = "scan from " + printable(publisher) + " refused: the scan topic belongs to " +
                      printable(scan_owner_.holder());
      NODELET_ERROR_THROTTLE(5.0, "%s", last_problem_.c_str());
      return false;
    }
    // The front end holds one laser's mounting: a scan from another frame (a second laser on the
    // topic, a driver restarted with another frame_id) would be read as if taken by the first,
    // and three of its stamps going back would restart the map.
    if (robot_ && bareFrame(msg.header.frame_id) != laser_frame_) {
      ++rejected_, ++other_frame_scans_;
      last_problem_ = "scan in frame " + printable(msg.header.frame_id) + " refused: this SLAM reads one laser, in frame " +
                      laser_frame_;
      NODELET_WARN_THROTTLE(5.0, "%s", last_problem_.c_str());
      return false;
    }
    return true;
  }

  void processScan(const sensor_msgs::LaserScan::ConstPtr& msg, const std::string& publisher) {
    std::lock_guard<std::mutex> lock(mutex_);
    const double t = msg->header.stamp.toSec();
    // Checked again: the topic may have found its owner while the scan waited for its odometry.
    if (!admissible(*msg, publisher)) return;
    const double wall = ros::WallTime::now().toSec();
    const std::string stamp_problem = stampProblem(msg->header.stamp);
    if (!stamp_problem.empty()) {
      ++rejected_;
      last_problem_ = stamp_problem;
      NODELET_WARN_THROTTLE(5.0, "scan refused: %s", stamp_problem.c_str());
      return;
    }
    if (!robot_ && !startFrontEnd(msg->header.frame_id)) return;
    if (use_odometry_ && !addOdometry(msg->header.stamp)) return;
    if (stamp_gate_->last() && params_.use_imu) integrateGyro(*stamp_gate_->last(), t);
    stamp_gate_->used(t);
    scan_owner_.take(publisher, wall);  // last, so that a scan refused above never claims the topic
    const slam::ScanStep step =
        robot_->processScan(laser_upside_down_ ? slam::uprightScan(scanFromMsg(*msg)) : scanFromMsg(*msg));
    if (!step.used) {
      ++rejected_;
      last_problem_ = step.reason;
      NODELET_WARN_THROTTLE(5.0, "scan rejected: %s", step.reason.c_str());
      return;
    }
    if (step.odometry_jump) NODELET_WARN_THROTTLE(5.0, "odometry jumped between two scans: the scan says the robot did not move");
    if (!step.gyro_problem.empty()) NODELET_ERROR("%s", step.gyro_problem.c_str());
    stamps_.push_back(msg->header.stamp);
    publishPose(msg->header.stamp);
    recordPoseLag(msg.get());
  }

  // The front end, once the laser's mounting on base_frame is known: the newest transform will
  // do (the laser is bolted on); a scan taken in base_frame itself needs none, so a bag with
  // nothing but scans runs with base_frame set to the laser's frame.
  bool startFrontEnd(const std::string& laser_frame) {  // mutex_ held
    slam::LaserMount mount;  // a scan taken in base_frame itself: upright at its origin
    if (bareFrame(laser_frame) != bareFrame(base_frame_)) {
      std::string error;
      const auto laser = lookupTransform(*tf_buffer_, base_frame_, bareFrame(laser_frame), ros::Time(0), &error);
      if (!laser) {
        NODELET_WARN_THROTTLE(5.0, "waiting for tf %s -> %s: %s", base_frame_.c_str(), laser_frame.c_str(), error.c_str());
        last_problem_ = "no laser transform: " + error;
        return false;
      }
      const auto mounted = slam::laserMount(quaternionOf(laser->rotation), laser->translation.x, laser->translation.y, &error);
      if (!mounted) {
        last_problem_ = mount_problem_ = "laser frame " + laser_frame + " refused: " + error;
        NODELET_ERROR_THROTTLE(5.0, "%s", last_problem_.c_str());
        return false;
      }
      mount = *mounted;
    }
    mount_problem_.clear();
    laser_frame_ = bareFrame(laser_frame);
    laser_upside_down_ = mount.upside_down;
    robot_ = slam::makeFrontEnd(params_, mount.pose);
    robot_->setOdometryAvailable(use_odometry_);
    return true;
  }

  // Hands the odometry's motion since the last scan to the front end; false (the scan is
  // refused) when odom_frame -> base_frame is not known at the scan's stamp.
  bool addOdometry(const ros::Time& stamp) {  // mutex_ held
    std::string error;
    const auto odom = lookupPose2D(*tf_buffer_, odom_frame_, base_frame_, stamp, &error);
    if (!odom || !finite(*odom)) {
      ++rejected_;
      last_problem_ = "no odometry at the scan's stamp: " + error;
      NODELET_WARN_THROTTLE(5.0, "%s", last_problem_.c_str());
      return false;
    }
    if (last_odom_) robot_->addOdometry(last_odom_->inverse().compose(*odom));
    last_odom_ = odom;
    return true;
  }

  // Wall seconds from a scan's arrival to its pose: the waits for odometry and gyro and the
  // front end (a bag's clock cannot measure it: it lags the scans under load). Kept for the
  // last kLagWindow scans (mutex_ held).
  void recordPoseLag(const sensor_msgs::LaserScan* scan) {
    const auto arrival = scan_arrivals_.find(scan);
    if (arrival == scan_arrivals_.end()) return;
    const double lag = ros::WallTime::now().toSec() - arrival->second;
    scan_arrivals_.erase(arrival);
    pose_lags_.push_back(lag);
    if (pose_lags_.size() > kLagWindow) pose_lags_.pop_front();
    max_pose_lag_ = std::max(max_pose_lag_, lag);
  }

  void publishPose(const ros::Time& stamp) {  // mutex_ held
    const Pose2D pose = robot_->pose();
    const Eigen::Matrix3d cov = robot_->covariance();
    const ros::Time tf_stamp = stamp + ros::Duration(transform_tolerance_);
    if (publish_tf_ && last_odom_) {
      // map -> odom = (map -> base) * (odom -> base)^-1 with the odometry the filter has used.
      const Pose2D map_to_odom = pose.compose(last_odom_->inverse());
      tf_broadcaster_->sendTransform(transformMsg(map_frame_, odom_frame_, tf_stamp, map_to_odom));
    } else if (publish_tf_ && !use_odometry_) {
      tf_broadcaster_->sendTransform(transformMsg(map_frame_, bareFrame(base_frame_), tf_stamp, pose));
    }
    auto pose_msg = boost::make_shared<geometry_msgs::PoseWithCovarianceStamped>();
    pose_msg->header.stamp = stamp;
    pose_msg->header.frame_id = map_frame_;
    pose_msg->pose.pose = poseToMsg(pose);
    fillCovariance(cov, pose_msg->pose.covariance);
    pose_pub_.publish(pose_msg);
    auto odom_msg = boost::make_shared<nav_msgs::Odometry>();
    odom_msg->header = pose_msg->header;
    odom_msg->child_frame_id = base_frame_;
    odom_msg->pose = pose_msg->pose;
    odom_pub_.publish(odom_msg);
  }

  // The map and the trajectory, each when it changed (a scan that adds nothing to the map
  // still adds a pose): pieces taken under the lock, composed outside.
  void onMapTimer(const ros::WallTimerEvent&) {
    std::vector<slam::MapPart> parts;
    std::vector<Pose2D> trajectory;
    std::vector<ros::Time> stamps;
    ros::Time stamp;
    bool map_changed = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!robot_ || stamps_.empty()) return;
      map_changed = robot_->mapVersion() != published_version_;
      if (!map_changed && stamps_.size() == published_poses_) return;
      published_version_ = robot_->mapVersion();
      published_poses_ = stamps_.size();
      if (map_changed) parts = robot_->mapParts();
      trajectory = robot_->trajectory();
      stamps = stamps_;
      stamp = stamps_.back();
    }
    publishTrajectory(trajectory, stamps);
    if (!map_changed) return;
    auto grid = boost::make_shared<nav_msgs::OccupancyGrid>();
    {
      std::lock_guard<std::mutex> compose_lock(compose_mutex_);
      const OccupancyGrid& composed = composer_.compose(parts);
      grid->data = composed.data;  // a copy: the composer keeps its map to merge only what changes
      gridToMsg(composed, map_frame_, stamp, *grid, /*with_data=*/false);
    }
    metadata_pub_.publish(grid->info);
    map_pub_.publish(nav_msgs::OccupancyGridConstPtr(grid));  // never modified after this line
    std::lock_guard<std::mutex> lock(mutex_);
    ++maps_published_;
    recent_addresses_.push_back(reinterpret_cast<uintptr_t>(grid.get()));
    if (recent_addresses_.size() > 20) recent_addresses_.pop_front();
  }

  // The latest estimate of the last trajectory_max_poses scans' poses (a robot running for
  // hours would otherwise publish an ever longer path every second).
  void publishTrajectory(const std::vector<Pose2D>& poses, const std::vector<ros::Time>& stamps) {
    auto path = boost::make_shared<nav_msgs::Path>();
    path->header.frame_id = map_frame_;
    path->header.stamp = stamps.empty() ? ros::Time(0) : stamps.back();
    const size_t n = std::min(poses.size(), stamps.size());
    for (size_t i = n - std::min(n, static_cast<size_t>(std::max(1, trajectory_max_poses_))); i < n; ++i) {
      geometry_msgs::PoseStamped p;
      p.header.frame_id = map_frame_;
      p.header.stamp = stamps[i];
      p.pose = poseToMsg(poses[i]);
      path->poses.push_back(p);
    }
    path_pub_.publish(nav_msgs::Path::ConstPtr(path));
  }

  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
    std::lock_guard<std::mutex> lock(mutex_);
    const slam::FrontEndStats s = robot_ ? robot_->stats() : slam::FrontEndStats{};
    const GuardedTransformListener::Refusals tf_refusals = tf_listener_->refusals();
    if (!params_problem_.empty()) status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, params_problem_);
    else if (!robot_ && !mount_problem_.empty()) status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, mount_problem_);
    else if (!s.gyro_problem.empty()) status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, s.gyro_problem);
    else if (!robot_) status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "waiting for scans and tf: " + last_problem_);
    else if (!use_odometry_ && !tf_refusals.holder.empty())
      // Both would be parents of base_frame: tf takes whichever came last.
      status.summary(diagnostic_msgs::DiagnosticStatus::WARN, printable(tf_refusals.holder) + " publishes " + odom_frame_ +
                                                                  " -> " + base_frame_ + " but use_odometry is false");
    else if (s.used > 10 && s.matched < s.used / 2) status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "fewer than half of the scans matched");
    else if (s.matchesOftenFailed())
      status.summary(diagnostic_msgs::DiagnosticStatus::WARN, std::to_string(s.used - s.matched) + " of " +
                                                                  std::to_string(s.used) +
                                                                  " scans not matched: the track leans on odometry");
    else if (s.scansOftenSeeLittle())
      status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                     std::to_string(s.few_returns) + " of " + std::to_string(s.used) +
                         " scans saw too little to correct the predicted motion: the map may drift");
    else if (s.revisitsRarelyConfirmed())
      status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                     "back in mapped places " + std::to_string(s.loop_attempts) + " times, the scans agreed " +
                         std::to_string(s.loop_accepted) + ": the map may be doubled or bent (a lost track?)");
    else if (s.odometryOftenOverruled())
      status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "the scans overruled the odometry on " +
                                                                  std::to_string(s.odometryOverruled()) + " of " +
                                                                  std::to_string(s.used) + " scans: is " + odom_frame_ +
                                                                  " this robot's wheel odometry?");
    else if (s.turnsOftenDoubted())
      status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "the scans doubted the odometry's heading on " +
                                                                  std::to_string(s.odometry_turns_doubted) + " of " +
                                                                  std::to_string(s.used) +
                                                                  " scans: it may have missed turns (a bent map?)");
    else status.summary(diagnostic_msgs::DiagnosticStatus::OK, "tracking");
    status.add("front end", robot_ ? robot_->name() : std::string("none yet"));
    status.add("motion from", use_odometry_ ? "odometry (" + odom_frame_ + " -> " + base_frame_ + ") and the scans"
                                            : std::string("the scans alone (use_odometry false)"));
    status.add("scans", s.used);
    status.add("scans matched", s.matched);
    status.add("matches gated out", s.gated);
    status.add("scans rejected", rejected_ + s.rejected);
    status.add("odometry jumps", s.odometry_jumps);
    status.add("odometry slips", s.odometry_slips);
    status.add("odometry increments driven backwards", s.odometry_reversals);
    status.add("turns the odometry missed", s.odometry_missed_turns);
    status.add("turns the odometry may have missed (not followed)", s.odometry_turns_doubted);
    status.add("scans placed by the correlative search alone", s.seeds_alone);
    status.add("scans with too few returns to correct the predicted motion", s.few_returns);
    status.add("correlative searches given up", s.searches_given_up);
    status.add("graph nodes", s.nodes);
    status.add("loop closures accepted", s.loop_accepted);
    status.add("loop closures dropped", s.loop_dropped);
    status.add("optimisation failures", s.optimization_failures);
    {
      std::lock_guard<std::mutex> input_lock(input_mutex_);
      status.add("imu samples rejected", imu_rejected_);
      status.add("imu samples without angular velocity", imu_without_rate_);
      status.add("scans whose gyro turn was set aside", s.gyro_set_aside);
      status.add("scans that waited for the gyro", scans_waited_for_gyro_.load());
      status.add("scans the gyro did not cover", scans_without_gyro_);
      status.add("odometry messages", odometry_messages_);
      status.add("odometry messages with NaN", bad_odometry_);
    }
    if (!pose_lags_.empty()) {
      double sum = 0, most = 0;
      for (double lag : pose_lags_) sum += lag, most = std::max(most, lag);
      status.add("pose lag behind its scan's arrival, mean of the last 100 (wall s)", sum / pose_lags_.size());
      status.add("pose lag behind its scan's arrival, most of the last 100 (wall s)", most);
    }
    status.add("pose lag behind its scan's arrival, most ever (wall s)", max_pose_lag_);
    status.add("resets (time jumps)", resets_);
    status.add("largest lead of a scan over the clock (s)", clock_lag_);
    status.add("scans refused from a second publisher", impostor_scans_);
    status.add("scans refused from another laser frame", other_frame_scans_);
    status.add("odometry transforms refused from a second publisher", tf_refusals.transforms);
    status.add("odometry publisher", tf_refusals.holder.empty() ? std::string("none yet") : printable(tf_refusals.holder));
    status.add("scan publisher", scan_owner_.holder().empty() ? std::string("none yet") : printable(scan_owner_.holder()));
    status.add("faults caught", faults_);
    status.add("maps published", maps_published_);
    status.add("last problem", s.last_problem.empty() ? last_problem_ : s.last_problem);
    // For the zero-copy test: subscribers in this manager must receive one of these objects.
    std::string addresses;
    for (uintptr_t a : recent_addresses_) addresses += std::to_string(a) + " ";
    status.add("recent map addresses", addresses);
  }

  // Lock rules. drain_mutex_ is held by the one thread processing the scans waiting for the
  // gyro (it takes mutex_ for each scan); waiting_mutex_ guards that line. mutex_ guards the
  // front end and what the scan callback shares with the map and diagnostics timers; the
  // scan callback holds it while the front end runs (scans are processed one at a time
  // anyway). The map timer takes the map's pieces and the trajectory
  // under it and composes and publishes them after releasing it, so the scan callback never
  // waits for a map to be composed. input_mutex_ guards the gyro buffer and the odometry/IMU
  // counters: the odometry and IMU callbacks take only it, so they never wait for a scan's
  // matching. Order: drain_mutex_, then waiting_mutex_ or mutex_, then input_mutex_.
  struct WaitingScan {
    ros::MessageEvent<sensor_msgs::LaserScan const> event;
    double arrived;  // wall s, out of the tf filter
  };
  static constexpr double kGyroWaitTick = 0.02;   // s (wall): how often waiting scans are looked at
  static constexpr size_t kMaxWaitingScans = 50;  // a longer line goes on without waiting
  std::mutex drain_mutex_;
  std::mutex waiting_mutex_;
  std::mutex mutex_;
  std::mutex input_mutex_;
  std::mutex compose_mutex_;
  slam::MapComposer composer_;  // compose_mutex_
  std::deque<WaitingScan> waiting_;  // waiting_mutex_
  std::atomic<bool> scans_waiting_{false};
  double imu_wait_ = 0.5;            // s (wall)
  std::string map_frame_, odom_frame_, base_frame_;
  bool publish_tf_ = true;
  bool use_odometry_ = true;  // false: a laser-only robot, each scan's motion found by matching
  double transform_tolerance_ = 0.1;
  double clock_lag_ = 0;  // the most a scan was stamped ahead of the clock
  int max_rays_ = 10000, trajectory_max_poses_ = 20000;
  std::unique_ptr<ScanStampGate> stamp_gate_;
  slam::GyroNoiseModel gyro_model_;
  slam::RobotSlamParams params_;
  std::unique_ptr<slam::FrontEnd> robot_;
  std::optional<Pose2D> last_odom_;
  std::vector<ros::Time> stamps_;  // of every scan the front end used, in order
  static constexpr size_t kLagWindow = 100;
  static constexpr size_t kMaxScanArrivals = 200;
  std::map<const sensor_msgs::LaserScan*, double> scan_arrivals_;  // wall s, of scans not yet used
  std::deque<double> pose_lags_;   // s, of the last kLagWindow poses
  double max_pose_lag_ = 0;
  slam::GyroBuffer gyro_;  // input_mutex_
  double gyro_heard_ = 0;  // wall s of the last gyro sample; input_mutex_
  std::optional<std::pair<std::string, Eigen::Quaterniond>> imu_mount_;  // the IMU's frame in base_frame; input_mutex_
  std::string laser_frame_;          // the laser the front end was started with (mutex_)
  bool laser_upside_down_ = false;  // its scans are mirrored into an upright laser's (mutex_)
  std::string mount_problem_;       // why the laser's mounting was refused (mutex_)
  uint64_t published_version_ = ~0ull;
  size_t published_poses_ = 0;
  size_t odometry_messages_ = 0, bad_odometry_ = 0, imu_rejected_ = 0;  // input_mutex_
  size_t imu_without_rate_ = 0;  // samples marked as measuring no angular velocity; input_mutex_
  std::atomic<size_t> scans_waited_for_gyro_{0};
  size_t scans_without_gyro_ = 0;     // input_mutex_
  size_t rejected_ = 0, resets_ = 0, maps_published_ = 0;
  size_t impostor_scans_ = 0;
  size_t other_frame_scans_ = 0;  // mutex_
  PublisherClaim scan_owner_;  // the node whose scans are used
  double input_owner_timeout_ = 5.0;
  size_t faults_ = 0;
  std::string last_problem_;
  std::string params_problem_;  // set once at start-up: the SLAM parameters given were refused
  std::deque<uintptr_t> recent_addresses_;  // of the last 20 grids published
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<GuardedTransformListener> tf_listener_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  ros::Publisher pose_pub_, odom_pub_, path_pub_, map_pub_, metadata_pub_;
  ros::Subscriber odom_sub_, imu_sub_;
  ros::Subscriber scan_sub_;
  std::unique_ptr<tf2_ros::MessageFilter<sensor_msgs::LaserScan>> scan_filter_;
  ros::WallTimer map_timer_, gyro_wait_timer_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
  ros::WallTimer diagnostics_timer_;
  ros::ServiceServer finish_srv_;
};

}  // namespace mrslam::nodelets

PLUGINLIB_EXPORT_CLASS(mrslam::nodelets::SlamNodelet, nodelet::Nodelet)
