// mrslam/MapMergeNodelet: fuses every peer's map into this robot's map (Saeedi et al. 2011
// map fusion, slam/fusion core), without a list of robots configured in advance.
//
// Subscribes: map (this robot's grid, by pointer from the mapping nodelet in the same manager),
// share_topic (mrslam/LocalMapShare of all robots) and compressed_share_topic
// (mrslam/CompressedMapShare, the same with the cells compressed; our own is ignored). The fusion runs in a
// worker thread, so callbacks never block. Publishes: the tf edge of the frame convention in
// fusion/peer_registry.h (static, robotP/map -> robotN/map), merged_map (OccupancyGrid in our
// map frame, latched), merge_status (diagnostic_msgs/DiagnosticArray, one status per peer:
// accepted, via (the peers it is placed through when its map does not overlap ours enough, empty
// when direct), x, y, yaw of the peer's map frame in ours, acceptance V, last estimate time, and
// stale: nothing heard from the peer for stale_after s; link_silent_s: how long ago data last
// arrived on the connection to it (one still being opened: how long it has been), -1 when none
// is open; while a stale peer's link is silent too, the share subscriptions are re-made every
// stale_after, see watchShareLinks), diagnostics; service ~export_octomap (std_srvs/Trigger)
// writes the merged map as an OctoMap .bt to the parameter octomap_path (default
// $ROS_HOME/<robot_id>_merged_map.bt, ~/.ros without ROS_HOME), whole or not at all.
//
// Fault containment: nothing a peer sends may take this robot down. A share is checked in the
// callback (id, grid structure, origin) and its grid again in the worker with exactly the
// checks the fusion makes (fusion::peerMapProblem) before it replaces the peer's last good map;
// a refused map is counted and named in diagnostics, and a peer refused bad_maps_to_quarantine
// times in a row is not listened to for quarantine_period s. A robot id belongs to the node that
// first shared under it; another publisher claiming it is refused as an impostor while the
// holder shares or is still registered with the master. Anything the worker still throws is
// caught, counted and logged with the peer it came from; the worker goes on.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/static_transform_broadcaster.h>

#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "mrslam/fusion/estimate_record.h"
#include "mrslam/fusion/fusion_params_io.h"
#include "mrslam/fusion/grid_merge.h"
#include "mrslam/fusion/map_fusion.h"
#include "mrslam/fusion/peer_quarantine.h"
#include "mrslam/fusion/peer_registry.h"
#include "mrslam/octomap_export.h"
#include "mrslam/publisher_claim.h"
#include "mrslam/ros/compressed_share.h"
#include "mrslam/ros/shared_map.h"
#include "master_query.h"
#include "ros_conversions.h"
#include "ros_params.h"
#include "share_codec.h"
#include "share_links.h"

namespace mrslam::nodelets {
namespace {

// Where roslaunch runs nodes and keeps its logs: $ROS_HOME, else ~/.ros. (Not /tmp: a robot's
// /tmp is emptied at every boot, and any user there can put a file of their own in the way.)
std::string rosHome() {
  if (const char* home = std::getenv("ROS_HOME"); home && *home) return home;
  if (const char* user = std::getenv("HOME"); user && *user) return std::string(user) + "/.ros";
  return ".";
}

}  // namespace

class MapMergeNodelet : public nodelet::Nodelet {
 public:
  ~MapMergeNodelet() override {
    stop_ = true;
    wake_.notify_all();
    if (worker_.joinable()) worker_.join();
  }

 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    const PrivateParams config(pnh);  // one call to the master for every key
    std::string topic, fusion_config;
    config.param<std::string>("robot_id", robot_id_, "robot1");
    config.param<std::string>("map_frame", map_frame_, robot_id_ + "/map");
    std::string compressed_topic;
    config.param<std::string>("share_topic", topic, "/mrslam/map_share");
    config.param<std::string>("compressed_share_topic", compressed_topic, "/mrslam/map_share_z");
    share_topics_ = {nh.resolveName(topic), nh.resolveName(compressed_topic)};
    config.param<std::string>("fusion_config", fusion_config, "");
    config.param<std::string>("octomap_path", octomap_path_, rosHome() + "/" + robot_id_ + "_merged_map.bt");
    config.param<std::string>("record_dir", record_dir_, "");
    config.param("max_peer_cells", max_peer_cells_, 64.0e6);
    config.param("merged_map_period", merged_map_period_, 2.0);
    fusion::PeerRegistryParams registry_params;
    config.param("regrow_fraction", registry_params.regrow_fraction, registry_params.regrow_fraction);
    config.param("consistent_m", registry_params.consistent_m, registry_params.consistent_m);
    config.param("consistent_deg", registry_params.consistent_deg, registry_params.consistent_deg);
    config.param("switch_margin", registry_params.switch_margin, registry_params.switch_margin);
    int min_known = static_cast<int>(registry_params.min_known_cells);
    config.param("min_known_cells", min_known, min_known);
    registry_params.min_known_cells = static_cast<size_t>(std::max(0, min_known));
    config.param("refresh_period", registry_params.refresh_period, registry_params.refresh_period);
    config.param("revoke_after_rejections", registry_params.revoke_after_rejections, registry_params.revoke_after_rejections);
    config.param("relay_min_vias", registry_params.relay_min_vias, registry_params.relay_min_vias);
    config.param("relay_agree_m", registry_params.relay_agree_m, registry_params.relay_agree_m);
    config.param("relay_agree_deg", registry_params.relay_agree_deg, registry_params.relay_agree_deg);
    registry_ = std::make_unique<fusion::PeerRegistry>(robot_id_, registry_params);
    const std::string registry_problem = fusion::peerRegistryParamsProblem(registry_params);
    if (!registry_problem.empty()) {  // as a refused fusion_config below: no merging on values nobody meant
      config_problem_ = "merge parameters refused: " + registry_problem;
      NODELET_ERROR("%s; this robot merges no peer maps until the parameter is fixed", config_problem_.c_str());
    }
    fusion::PeerQuarantineParams quarantine_params;
    config.param("bad_maps_to_quarantine", quarantine_params.bad_maps_in_a_row, quarantine_params.bad_maps_in_a_row);
    config.param("quarantine_period", quarantine_params.period_s, quarantine_params.period_s);
    quarantine_ = fusion::PeerQuarantine(quarantine_params);
    config.param("max_peers", max_peers_, max_peers_);
    config.param("owner_timeout", owner_timeout_, owner_timeout_);
    config.param("stale_after", stale_after_, stale_after_);
    if (!fusion_config.empty()) {
      try {
        fusion_params_ = fusion::loadFusionParams(fusion_config);
      } catch (const std::exception& e) {
        // Merging with parameters nobody chose would be worse than not merging: refuse, say so
        // in the log and in diagnostics, and leave the rest of the robot running.
        config_problem_ = std::string("fusion_config refused: ") + e.what();
        NODELET_ERROR("%s; this robot merges no peer maps until the file is fixed", config_problem_.c_str());
      }
    }

    merged_pub_ = nh.advertise<nav_msgs::OccupancyGrid>("merged_map", 1, true);
    status_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("merge_status", 1, true);
    diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
    diagnostics_->setHardwareID(nh.getNamespace());
    diagnostics_->add("map merge", this, &MapMergeNodelet::diagnose);
    diagnostics_timer_ = nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) {
      diagnostics_->force_update();
      watchShareLinks();
    });
    if (!config_problem_.empty()) {
      // merge_status is latched: whoever watches it learns why this robot merges nothing.
      auto array = boost::make_shared<diagnostic_msgs::DiagnosticArray>();
      array->header.stamp = ros::Time::now();
      diagnostic_msgs::DiagnosticStatus status;
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      status.name = robot_id_;
      status.message = config_problem_;
      array->status.push_back(status);
      status_pub_.publish(diagnostic_msgs::DiagnosticArray::ConstPtr(array));
      return;
    }
    own_sub_ = nh.subscribe("map", 1, &MapMergeNodelet::onOwnMap, this);
    subscribeShares();
    export_srv_ = pnh.advertiseService("export_octomap", &MapMergeNodelet::onExport, this);
    worker_ = std::thread(&MapMergeNodelet::work, this);
  }

  void subscribeShares() {
    ros::NodeHandle& nh = getNodeHandle();
    share_sub_ = nh.subscribe(share_topics_[0], 20, &MapMergeNodelet::onShare, this);
    compressed_share_sub_ = nh.subscribe(share_topics_[1], 20, &MapMergeNodelet::onCompressedShare, this);
  }

  // A peer silent for stale_after is out of range, down, behind a link that came back while TCP
  // still backs its retransmissions off (after an outage, the first retry may come as late as
  // the outage was long), or behind a slow link its map takes longer than stale_after to cross.
  // The connection's socket tells them apart: data still arriving is a slow link, left alone
  // (re-made, the map in flight would start again, and on a saturated link never arrive). For
  // the others, dropping and re-making the share subscriptions opens fresh connections to every
  // publisher the master lists, so a returned peer is heard again within stale_after of its
  // return; at most once per stale_after. Healthy peers lose at most the share in flight.
  void watchShareLinks() {
    const double now = ros::WallTime::now().toSec();
    std::map<std::string, std::string> holders;  // peer id -> its publisher's node
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!config_problem_.empty()) return;
      for (const auto& [id, peer] : registry_->peers()) holders[id] = owners_[id].holder();
    }
    const std::map<std::string, double> silence = shareLinkSilence(share_topics_, opening_since_, now);
    std::map<std::string, std::optional<double>> link_silent;
    for (const auto& [id, node] : holders) {
      const std::optional<std::string> uri = publisherUri(node);
      const auto link = uri ? silence.find(*uri) : silence.end();
      link_silent[id] = link != silence.end() ? std::optional<double>(link->second) : std::nullopt;
    }
    std::string dead;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      link_silent_ = link_silent;
      last_link_check_ = now;
      for (const auto& [id, link] : link_silent)
        if (silentFor(id, now) > stale_after_ && linkIsDead(link, stale_after_)) dead += (dead.empty() ? "" : ", ") + id;
      if (dead.empty() || now - last_reconnect_ < stale_after_) return;
      last_reconnect_ = now;
      ++share_reconnects_;
    }
    forgetPublisherUris();  // a peer that restarted listens on a new port
    NODELET_WARN_THROTTLE(60.0, "nothing heard from %s for %.0f s, nor on its link (stale): re-making the share subscriptions",
                          dead.c_str(), stale_after_);
    share_sub_.shutdown();  // the last handle of each topic in this process: its connections close
    compressed_share_sub_.shutdown();
    subscribeShares();
  }

  // The XML-RPC URI of a peer's publishing node, asked of the master once and kept.
  std::optional<std::string> publisherUri(const std::string& node) {
    if (node.empty()) return std::nullopt;
    std::lock_guard<std::mutex> lock(master_mutex_);
    const auto known = publisher_uris_.find(node);
    if (known != publisher_uris_.end()) return known->second;
    const std::optional<std::string> uri = uriOfNode(node);
    if (uri) publisher_uris_[node] = *uri;
    return uri;
  }
  void forgetPublisherUris() {
    std::lock_guard<std::mutex> lock(master_mutex_);
    publisher_uris_.clear();
  }

  // Wall seconds since the peer's last share (mutex_ held).
  double silentFor(const std::string& id, double now) { return now - owners_[id].lastHeard(); }

  void onOwnMap(const nav_msgs::OccupancyGrid::ConstPtr& map) {
    std::lock_guard<std::mutex> lock(mutex_);
    own_msg_ = map;
    own_address_ = reinterpret_cast<uintptr_t>(map.get());
    own_dirty_ = true;
    wake_.notify_one();
  }

  void onShare(const ros::MessageEvent<SharedMap const>& event) {
    const SharedMap::ConstPtr share = event.getConstMessage();
    try {
      if (!admitShare(share->robot_id, event.getPublisherName())) return;
      const std::string problem =
          share->map ? gridMsgProblem(*share->map, static_cast<int64_t>(max_peer_cells_)) : std::string("no map");
      queueShare(share, event.getPublisherName(), problem);
    } catch (const std::exception& e) {
      recordFault("share of '" + printable(share->robot_id) + "'", e.what());
    }
  }

  // A compressed share becomes the LocalMapShare it encodes, once its sender is admitted; the
  // cells are inflated only when the grid's header is usable, and never beyond its size.
  void onCompressedShare(const ros::MessageEvent<ReceivedCompressedShare const>& event) {
    const CompressedMapShare* msg = &event.getConstMessage()->msg;
    try {
      if (!admitShare(msg->robot_id, event.getPublisherName())) return;
      auto grid = boost::make_shared<nav_msgs::OccupancyGrid>();
      const std::string problem = inflateGrid(*msg, static_cast<int64_t>(max_peer_cells_), *grid);
      auto share = boost::make_shared<SharedMap>();
      share->header = msg->header;
      share->robot_id = msg->robot_id;
      share->map = grid;
      share->pose = msg->pose;
      share->version = msg->version;
      queueShare(share, event.getPublisherName(), problem);
    } catch (const std::exception& e) {
      recordFault("share of '" + printable(msg->robot_id) + "'", e.what());
    }
  }

  // The callback's checks on who sent a share (cheap, before anything is decoded): a valid id,
  // not ours, not an impostor's, not quarantined, within max_peers. Refusals are counted here.
  bool admitShare(const std::string& id, const std::string& publisher) {
    if (id == robot_id_) return false;
    if (!fusion::isValidRobotId(id)) {
      refuseMap(id, "robot_id is not a valid tf prefix ([a-zA-Z][a-zA-Z0-9_]*, at most 64 characters)",
                /*count_against_peer=*/false);
      return false;
    }
    if (heldByAnother(id, publisher)) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++impostor_shares_;
      last_problem_ = "map of '" + id + "' from " + printable(publisher) + " refused: the id belongs to " +
                      printable(owners_[id].holder());
      NODELET_ERROR_THROTTLE(5.0, "%s", last_problem_.c_str());
      return false;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    if (quarantine_.isQuarantined(id, ros::WallTime::now().toSec())) {
      ++quarantined_shares_;
      return false;
    }
    if (!registry_->peers().count(id) && !pending_.count(id) &&
        registry_->peers().size() + pending_.size() >= static_cast<size_t>(std::max(0, max_peers_))) {
      ++rejected_maps_;
      last_problem_ = "map of '" + id + "' refused: already " + std::to_string(max_peers_) + " peers (max_peers)";
      NODELET_ERROR_THROTTLE(5.0, "%s", last_problem_.c_str());
      return false;
    }
    return true;
  }

  // An admitted share whose grid has `problem` is refused (and counted against the peer);
  // otherwise it is the newest map of its peer. The worker converts it when it gets to it, so
  // the callback never copies a grid and maps superseded in the meantime are never copied.
  void queueShare(const SharedMap::ConstPtr& share, const std::string& publisher, const std::string& problem) {
    if (!problem.empty()) {
      refuseMap(share->robot_id, problem);
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    owners_[share->robot_id].take(publisher, ros::WallTime::now().toSec());
    pending_[share->robot_id] = share;
    wake_.notify_one();
  }

  // A robot id belongs to the node that first shared under it: a second publisher claiming it
  // is an impostor, refused and reported, never merged, and not counted against the real peer.
  // The holder keeps the id while it shares, and while the master still lists it as a
  // publisher of the share topic (a robot whose map stops changing stops sharing); a holder
  // silent for owner_timeout and gone from the master frees it (a peer restarted under a new
  // node name takes it over).
  bool heldByAnother(const std::string& id, const std::string& publisher) {
    std::string holder;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const PublisherClaim& owner = owners_[id];
      if (owner.heldByAnother(publisher, ros::WallTime::now().toSec(), owner_timeout_)) return true;
      if (owner.holder().empty() || owner.holder() == publisher) return false;
      holder = owner.holder();
    }
    return stillPublishing(holder);
  }

  // Whether the master lists `node` as a publisher of the share topic (asked at most every 2 s:
  // an impostor's flood must not become a flood of calls to the master). Unknown counts as yes.
  bool stillPublishing(const std::string& node) {
    std::lock_guard<std::mutex> lock(master_mutex_);  // not mutex_: the callbacks never wait for the master
    const double now = ros::WallTime::now().toSec();
    if (now - master_asked_ >= 2.0) {
      master_publishers_ = publishersOf(share_topics_);
      master_asked_ = now;
    }
    return !master_publishers_ || master_publishers_->count(node);
  }

  // A map of `id` cannot be used: counted, named in diagnostics, logged (throttled) and, when
  // `count_against_peer`, counted towards the peer's quarantine.
  void refuseMap(const std::string& id, const std::string& problem, bool count_against_peer = true) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++rejected_maps_;
    last_problem_ = "map of '" + printable(id) + "' refused: " + problem;
    NODELET_ERROR_THROTTLE(5.0, "%s", last_problem_.c_str());
    if (count_against_peer && quarantine_.reportBad(id, ros::WallTime::now().toSec()))
      NODELET_WARN("peer '%s' quarantined for %.0f s: its maps were refused %d times in a row (last: %s)", id.c_str(),
                   quarantine_.params().period_s, quarantine_.params().bad_maps_in_a_row, problem.c_str());
  }

  // A kept peer map turned out unusable: the peer is forgotten and the map refused.
  void forgetPeer(const std::string& id, const std::string& problem) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      registry_->forget(id);
    }
    refuseMap(id, problem);
  }

  // An exception that escaped a step: counted and logged with where it came from.
  void recordFault(const std::string& where, const std::string& what) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++faults_;
    last_problem_ = where + ": " + what;
    NODELET_ERROR_THROTTLE(5.0, "caught: %s", last_problem_.c_str());
  }

  // What the callbacks left for the worker, taken under the lock in one go.
  struct Inbox {
    nav_msgs::OccupancyGrid::ConstPtr own;              // set when our map changed
    std::map<std::string, SharedMap::ConstPtr> shares;  // newest unconverted map of each peer
  };

  Inbox takeInbox() {
    std::unique_lock<std::mutex> lock(mutex_);
    wake_.wait_for(lock, std::chrono::milliseconds(500));
    Inbox in;
    if (own_dirty_) in.own = own_msg_;
    own_dirty_ = false;
    // A peer's map is stamped with our clock when it is admitted (first_map_time and every
    // delay after it). Under sim time our clock reads 0 until our own bag or driver starts it,
    // and a robot switched on after its peers hears their maps before that: those maps wait
    // here (the newest of each peer), so that no peer is ever first seen at time 0.
    if (!ros::Time::now().isZero()) in.shares.swap(pending_);
    return in;
  }

  // The worker: one fusion at a time, never inside a callback, never holding the lock while
  // converting a grid or fusing.
  void work() {
    while (!stop_) {
      Inbox in = takeInbox();
      if (stop_) return;
      try {
        step(in);
      } catch (const std::exception& e) {
        recordFault("merge worker", e.what());
      } catch (...) {
        recordFault("merge worker", "unknown exception");
      }
    }
  }

  void step(const Inbox& in) {
    if (in.own) takeOwnMap(*in.own);
    for (const auto& [id, share] : in.shares) admitPeerMap(id, *share);
    estimateNext();
    // The merged map is rebuilt when a transform changed, or when our map changed and the
    // last rebuild is older than merged_map_period; never for nothing.
    std::shared_ptr<const OccupancyGrid> own;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      own = own_grid_;
    }
    const ros::WallTime now = ros::WallTime::now();
    if (own && (merged_due_ || (own_changed_since_merge_ && (now - last_merged_).toSec() >= merged_map_period_)))
      publishMerged(own);
  }

  void takeOwnMap(const nav_msgs::OccupancyGrid& msg) {
    auto grid = std::make_shared<const OccupancyGrid>(gridFromMsg(msg));
    const fusion::MapSummary summary = fusion::summarize(*grid);
    std::lock_guard<std::mutex> lock(mutex_);
    own_grid_ = std::move(grid);
    own_summary_ = summary;
    own_changed_since_merge_ = true;
  }

  // A peer's map replaces its last good one only if the fusion could take it.
  void admitPeerMap(const std::string& id, const SharedMap& share) {
    auto grid = std::make_shared<const OccupancyGrid>(gridFromMsg(*share.map));
    double own_resolution = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (own_grid_) own_resolution = own_grid_->resolution;
    }
    const std::string problem = fusion::peerMapProblem(*grid, own_resolution, fusion_params_);
    if (!problem.empty()) {
      refuseMap(id, problem);
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    quarantine_.reportGood(id);
    if (registry_->updatePeer(id, std::move(grid), share.version, ros::Time::now().toSec()))
      NODELET_INFO("discovered peer %s", id.c_str());
  }

  void estimateNext() {
    std::shared_ptr<const OccupancyGrid> own, peer_map;
    std::string peer_id;
    fusion::MapSummary own_summary;
    std::optional<Pose2D> held;  // the transform we hold: the search verifies it again too
    std::optional<std::pair<std::string, std::string>> relay_job;  // {peer, via} when no direct estimate is due
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!own_grid_) return;
      own = own_grid_;
      own_summary = own_summary_;
      if (auto next = registry_->nextToEstimate(own_summary, ros::WallTime::now().toSec())) {
        peer_id = *next;
        const fusion::Peer& peer = registry_->peers().at(peer_id);
        peer_map = peer.map;
        if (peer.accepted) held = peer.accepted->pose;
      } else if (auto relay = registry_->nextRelayToEstimate(ros::WallTime::now().toSec())) {
        relay_job = *relay;
      } else {
        if (!registry_->peers().empty() && (ros::WallTime::now() - last_status_).toSec() >= 1.0)
          publishStatus();  // once a second without news: whether each estimate is still current
        return;
      }
    }
    if (relay_job) {
      estimateRelay(relay_job->first, relay_job->second);
      return;
    }
    // Our own map may not be fusable yet (no walls): that is nobody's fault, wait for it. A peer
    // map admitted before our resolution was known may still be refused here.
    if (!fusion::checkFusable(*own, fusion_params_).empty()) return;
    const std::string problem = fusion::peerMapProblem(*peer_map, own->resolution, fusion_params_);
    if (!problem.empty()) {
      forgetPeer(peer_id, problem);
      return;
    }
    fusion::FusionResult result;
    try {
      result = fusion::alignMaps(*own, *peer_map, fusion_params_, held);
    } catch (const std::exception& e) {
      forgetPeer(peer_id, std::string("fusion failed: ") + e.what());
      return;
    }
    record(peer_id, "", *own, *peer_map, held, result);
    std::lock_guard<std::mutex> lock(mutex_);
    if (!registry_->peers().count(peer_id)) return;
    const bool had = registry_->peers().at(peer_id).accepted.has_value();
    if (registry_->applyEstimate(peer_id, result, own_summary, ros::Time::now().toSec(), ros::WallTime::now().toSec())) {
      if (!registry_->peers().at(peer_id).accepted)
        NODELET_WARN("transform to %s revoked: rejected %d times in a row on grown maps (%s)", peer_id.c_str(),
                     registry_->peers().at(peer_id).rejections_in_a_row, result.verdict.reason.c_str());
      else if (!had)  // the first accept is news; refinements are not
        NODELET_INFO("transform to %s: (%.2f, %.2f, %.1f deg), V %.3f", peer_id.c_str(), result.pose.x,
                     result.pose.y, result.pose.yaw * 180 / M_PI, result.verdict.acceptance);
      publishParentEdge();
      merged_due_ = true;
    }
    publishStatus();
  }

  // A peer we have not accepted, aligned to the map of a peer we have (`via`): the same fusion
  // and verification as a direct estimate, only against via's map instead of ours.
  void estimateRelay(const std::string& peer_id, const std::string& via_id) {
    std::shared_ptr<const OccupancyGrid> peer_map, via_map;
    std::optional<Pose2D> held;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const auto& peers = registry_->peers();
      if (!peers.count(peer_id) || !peers.count(via_id)) return;
      peer_map = peers.at(peer_id).map;
      via_map = peers.at(via_id).map;
      const auto relay = peers.at(peer_id).relays.find(via_id);
      if (relay != peers.at(peer_id).relays.end() && relay->second.accepted) held = relay->second.accepted->pose;
    }
    fusion::FusionResult result;
    try {
      result = fusion::alignMaps(*via_map, *peer_map, fusion_params_, held);
    } catch (const std::exception& e) {  // both maps passed peerMapProblem: a fault, not the peer's
      recordFault("relay " + peer_id + " via " + via_id, e.what());
      return;
    }
    record(peer_id, via_id, *via_map, *peer_map, held, result);
    std::lock_guard<std::mutex> lock(mutex_);
    if (registry_->applyRelayEstimate(peer_id, via_id, result, ros::Time::now().toSec(), ros::WallTime::now().toSec()))
      merged_due_ = true;
    publishStatus();
  }

  // With record_dir set, the maps and outcome of every estimate (estimate_record.h), so that
  // any merge this robot made or refused replays offline with mrslam_merge. A full disk costs
  // the records, never the merge.
  void record(const std::string& peer, const std::string& via, const OccupancyGrid& a, const OccupancyGrid& b,
              const std::optional<Pose2D>& held, const fusion::FusionResult& result) {
    if (record_dir_.empty()) return;
    try {
      fusion::recordEstimate(record_dir_, peer, via, a, b, held, result, ros::WallTime::now().toSec());
    } catch (const std::exception& e) {
      NODELET_ERROR_THROTTLE(60.0, "record_dir: %s; merging goes on without records", e.what());
    }
  }

  void publishParentEdge() {  // mutex_ held
    const auto parent = registry_->parentOf();
    if (!parent) return;
    // The static broadcaster keeps one transform per child frame: this replaces the previous edge.
    const Pose2D parent_in_ours = registry_->peers().at(*parent).accepted->pose;
    static_broadcaster_.sendTransform(transformMsg(*parent + "/map", map_frame_, ros::Time(0), parent_in_ours.inverse()));
  }

  void publishMerged(const std::shared_ptr<const OccupancyGrid>& own) {
    std::vector<std::shared_ptr<const OccupancyGrid>> keep;  // alive while merging unlocked
    std::vector<fusion::PlacedGrid> placed;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const auto& [id, peer] : registry_->peers()) {
        const std::optional<fusion::Placement> where = registry_->placementOf(peer);
        if (where && peer.map) {
          keep.push_back(peer.map);
          placed.push_back({peer.map.get(), where->pose});
        }
      }
      merged_due_ = false;
      own_changed_since_merge_ = false;
    }
    last_merged_ = ros::WallTime::now();
    OccupancyGrid merged = placed.empty() ? *own : fusion::mergeGrids(*own, placed);
    auto msg = boost::make_shared<nav_msgs::OccupancyGrid>();
    std::swap(merged.data, msg->data);  // the cells move into the message, no copy
    gridToMsg(merged, map_frame_, ros::Time::now(), *msg, /*with_data=*/false);
    nav_msgs::OccupancyGrid::ConstPtr published(msg);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      merged_ = published;  // for the OctoMap export; never modified
    }
    merged_pub_.publish(published);
  }

  void publishStatus() {  // mutex_ held
    auto array = boost::make_shared<diagnostic_msgs::DiagnosticArray>();
    array->header.stamp = ros::Time::now();
    for (const auto& [id, peer] : registry_->peers()) {
      diagnostic_updater::DiagnosticStatusWrapper s;
      s.name = id;
      s.hardware_id = robot_id_;
      const std::optional<fusion::Placement> placed = registry_->placementOf(peer);
      s.summary(placed ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::WARN,
                verdictOf(peer, placed));
      s.add("accepted", placed.has_value());  // merged: directly or through a relay
      s.add("via", placed ? joined(placed->vias) : std::string());
      const PeerEstimateView e = view(peer, placed);
      s.add("x", e.x);
      s.add("y", e.y);
      s.add("yaw", e.yaw);
      s.add("acceptance", e.acceptance);
      s.add("last_estimate_time", peer.last_attempt.stamp);
      s.add("first_map_time", peer.first_seen);
      s.add("accepted_since", placed ? placed->since : peer.accepted_since);
      s.add("attempts", peer.attempts);
      s.add("estimate_current", registry_->estimateIsCurrent(peer, own_summary_));
      s.add("version", peer.version);
      s.add("relays", relaysOf(peer));
      // A robot re-sends an unchanged map every share_keyframe_period: silence beyond
      // stale_after means its link (or the robot) is down. Its last estimate stays in use.
      const double silent = silentFor(id, ros::WallTime::now().toSec());
      s.add("heard_s_ago", silent);
      s.add("stale", silent > stale_after_);
      const auto link = link_silent_.find(id);
      s.add("link_silent_s", link != link_silent_.end() && link->second ? *link->second : -1.0);
      // The links are read once a second: an older reading means the check itself is stuck
      // (link_silent_s frozen, no re-made subscription), not the peer.
      s.add("link_checked_s_ago", last_link_check_ > 0 ? ros::WallTime::now().toSec() - last_link_check_ : -1.0);
      array->status.push_back(s);
    }
    status_pub_.publish(diagnostic_msgs::DiagnosticArray::ConstPtr(array));
    last_status_ = ros::WallTime::now();
  }

  // The status message: a held transform whose latest re-estimate was rejected says so (it is
  // not current); a relayed peer names the peers it is placed through.
  static std::string verdictOf(const fusion::Peer& peer, const std::optional<fusion::Placement>& placed) {
    if (placed && !placed->vias.empty())
      return "accepted via " + joined(placed->vias) + " (directly: " + peer.last_attempt.reason + ")";
    if (!placed) return "not accepted: " + peer.last_attempt.reason;
    if (peer.last_attempt.accepted) return "accepted";
    return "accepted (held; the last re-estimate was not: " + peer.last_attempt.reason + ")";
  }

  // Each relay tried for a peer: "via tries accepted|rejected", the rejections with their last
  // reason ("robot1 3 accepted; robot2 2 rejected: acceptance index V 0.951 < 0.97"): a peer
  // not placed tells relays never tried (the worker busy with direct estimates) from relays
  // that disagree or fail.
  static std::string relaysOf(const fusion::Peer& peer) {
    std::string out;
    for (const auto& [via, relay] : peer.relays) {
      if (relay.attempts == 0) continue;
      out += (out.empty() ? "" : "; ") + via + " " + std::to_string(relay.attempts) +
             (relay.accepted ? " accepted" : " rejected: " + relay.last_attempt.reason);
    }
    return out;
  }

  static std::string joined(const std::vector<std::string>& ids) {
    std::string out;
    for (const std::string& id : ids) out += (out.empty() ? "" : " ") + id;
    return out;
  }

  struct PeerEstimateView {
    double x = 0, y = 0, yaw = 0, acceptance = 0;
  };
  static PeerEstimateView view(const fusion::Peer& peer, const std::optional<fusion::Placement>& placed) {
    if (placed) return {placed->pose.x, placed->pose.y, placed->pose.yaw, placed->acceptance};
    const fusion::PeerEstimate& e = peer.last_attempt;
    return {e.pose.x, e.pose.y, e.pose.yaw, e.acceptance};
  }

  bool onExport(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    nav_msgs::OccupancyGrid::ConstPtr merged;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      merged = merged_;
    }
    if (!merged) {
      response.success = false;
      response.message = "no merged map yet";
      return true;
    }
    try {
      std::error_code ignored;  // a folder that cannot be made: the write below says so
      std::filesystem::create_directories(std::filesystem::path(octomap_path_).parent_path(), ignored);
      const size_t voxels = saveOctomap(gridFromMsg(*merged), octomap_path_);
      response.success = true;
      response.message = octomap_path_ + ": " + std::to_string(voxels) + " leaf voxels";
    } catch (const std::exception& e) {
      response.success = false;
      response.message = e.what();
    }
    return true;
  }

  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!config_problem_.empty()) {
      status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, config_problem_);
      return;
    }
    size_t accepted = 0;
    for (const auto& [id, peer] : registry_->peers()) accepted += registry_->placementOf(peer).has_value();
    status.summary((rejected_maps_ || faults_) && !last_problem_.empty() ? diagnostic_msgs::DiagnosticStatus::WARN
                                                                          : diagnostic_msgs::DiagnosticStatus::OK,
                   std::to_string(accepted) + " of " + std::to_string(registry_->peers().size()) + " peers merged");
    status.add("peer maps rejected", rejected_maps_);
    status.add("faults caught", faults_);
    std::string quarantined;
    for (const std::string& id : quarantine_.quarantined(ros::WallTime::now().toSec())) quarantined += id + " ";
    status.add("peers quarantined", quarantined);
    status.add("shares dropped from quarantined peers", quarantined_shares_);
    status.add("shares refused from impostors", impostor_shares_);
    status.add("share reconnects (a stale peer's link was silent too)", share_reconnects_);
    status.add("last problem", last_problem_);
    // For the zero-copy test: the address of the last own map object received.
    status.add("own map address", std::to_string(own_address_));
    const auto parent = registry_->parentOf();
    status.add("tf parent", parent ? *parent + "/map" : std::string("none (root)"));
  }

  // Lock rules. Threads: the ROS callbacks (onOwnMap, onShare, onExport, the diagnostics timer)
  // and the worker. mutex_ guards every member both touch (registry, quarantine, owners, pending
  // and own maps, counters, last_problem_, merged_). Only the worker touches merged_due_,
  // own_changed_since_merge_, last_merged_ and last_status_, without the lock. The worker never
  // holds mutex_ while it converts a grid, fuses or composes the merged map.
  std::mutex mutex_;
  std::condition_variable wake_;
  std::atomic<bool> stop_{false};
  std::thread worker_;
  std::string robot_id_, map_frame_, octomap_path_, last_problem_;
  std::string record_dir_;  // set in onInit: where every estimate is recorded (empty: nowhere)
  std::string config_problem_;  // set once in onInit (before any callback) when fusion_config or a
                                // merge parameter is refused
  std::vector<std::string> share_topics_;  // resolved: plain and compressed
  double max_peer_cells_ = 64e6, merged_map_period_ = 2.0;
  fusion::FusionParams fusion_params_;
  std::unique_ptr<fusion::PeerRegistry> registry_;
  fusion::PeerQuarantine quarantine_;
  int max_peers_ = 32;
  std::map<std::string, PublisherClaim> owners_;  // who holds each robot id
  std::mutex master_mutex_;  // guards the master's answers (onShare threads, the diagnostics timer)
  std::optional<std::set<std::string>> master_publishers_;
  std::map<std::string, std::string> publisher_uris_;  // publishing node -> its XML-RPC URI
  std::map<std::string, std::optional<double>> link_silent_;  // peer id -> s since data arrived on its link
  double last_link_check_ = 0;  // wall s of the last watchShareLinks that read the links
  OpeningSince opening_since_;  // share connections being opened (the diagnostics timer's own)
  double master_asked_ = -1e18;
  double owner_timeout_ = 30.0, stale_after_ = 90.0;
  size_t impostor_shares_ = 0, share_reconnects_ = 0;
  double last_reconnect_ = -1e18;  // wall s
  nav_msgs::OccupancyGrid::ConstPtr own_msg_;
  std::shared_ptr<const OccupancyGrid> own_grid_;
  nav_msgs::OccupancyGrid::ConstPtr merged_;
  std::map<std::string, SharedMap::ConstPtr> pending_;  // newest unconverted map of each peer
  fusion::MapSummary own_summary_;
  size_t rejected_maps_ = 0, faults_ = 0, quarantined_shares_ = 0;
  uintptr_t own_address_ = 0;
  bool own_dirty_ = false, merged_due_ = false, own_changed_since_merge_ = false;
  ros::WallTime last_merged_, last_status_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
  ros::Publisher merged_pub_, status_pub_;
  ros::Subscriber own_sub_, share_sub_, compressed_share_sub_;
  ros::ServiceServer export_srv_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
  ros::WallTimer diagnostics_timer_;
};

}  // namespace mrslam::nodelets

PLUGINLIB_EXPORT_CLASS(mrslam::nodelets::MapMergeNodelet, nodelet::Nodelet)
