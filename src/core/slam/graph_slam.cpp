#include "mrslam/slam/graph_slam.h"

#include <algorithm>
#include <chrono>

#include "mrslam/slam/ekf_front_end.h"
#include "mrslam/slam/pose_refinement.h"
#include "mrslam/slam/stretch_reanchor.h"

namespace mrslam::slam {

namespace {
constexpr int kMaxOutlierRounds = 3;  // optimise, drop the closures the optimum disagrees with, repeat
constexpr int kTiedNeighbours = 5;    // nodes either side of one tied to a submap count as tied to it
}  // namespace

GraphSlam::GraphSlam(const RobotSlamParams& params, const Pose2D& laser_in_base)
    : params_(params),
      tracker_(params, laser_in_base),
      closer_(params.graph, params.matcher),
      solver_(makePoseGraphSolver(params.graph.solver, PoseGraphSolverParams{params.graph.solver_iterations, 1.0})) {}

void GraphSlam::reset() {
  tracker_.reset();
  closer_.clear();
  nodes_.clear();
  poses_.clear();
  edges_.clear();
  submaps_.clear();
  scans_.clear();
  travel_ = 0;
  weak_since_node_ = false;
  pending_.clear();
  doubted_splits_.clear();
  unoptimized_closures_ = nodes_since_optimization_ = 0;
  last_tracker_pose_ = Pose2D{};
  stats_ = FrontEndStats{};
  ++map_version_;
}

namespace {
double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}
}  // namespace

ScanStep GraphSlam::processScan(const LaserScan& scan) {
  const auto start = std::chrono::steady_clock::now();
  ScanStep step = tracker_.track(scan);
  stats_.tracking_ms += msSince(start);
  countStep(step, stats_);
  if (!step.used) return step;
  // How much the tracker's motion since the last node can be trusted.
  const bool weak = !step.matched || step.odometry_jump || step.odometry_slipped || step.odometry_reversed ||
                    step.match.goodness < params_.graph.weak_match_goodness;
  const Pose2D tracker_pose = tracker_.filter().pose();
  if (!nodes_.empty())
    travel_ += std::hypot(tracker_pose.x - last_tracker_pose_.x, tracker_pose.y - last_tracker_pose_.y);
  last_tracker_pose_ = tracker_pose;
  // After finish() the active submap is closed: the next scan starts a node and a new submap.
  if (isNewNode(tracker_pose) || activeSubmap().finished()) addNode(scan, tracker_pose, weak_since_node_, weak, step);
  else weak_since_node_ = weak_since_node_ || weak;
  const int node = static_cast<int>(nodes_.size()) - 1;
  // The turn the odometry may have missed lies before this node if the scan became one, else
  // before the next.
  const int split = step.new_node ? node : node + 1;
  if (step.odometry_turn_doubted && (doubted_splits_.empty() || doubted_splits_.back() != split))
    doubted_splits_.push_back(split);
  const Pose2D offset = nodes_.back().tracker_pose.inverse().compose(tracker_pose);
  Submap& submap = activeSubmap();
  submap.insert(scan, node, offset, trackedInAnchor(submap, node), optimizedInAnchor(submap, node));
  scans_.push_back({node, offset});
  ++map_version_;
  return step;
}

void GraphSlam::addTrackerEdges(int n) {
  if (n == 0) return;
  edges_.push_back(odometryEdge(n - 1, n, weakEdge(n)));
  // A scan matched poorly between two matched well (scans metres apart that share little with
  // the map: Intel every 5th, 2-7 degrees off) puts its node off alone. The motion into it and
  // out of it is as unsure as the node (both weak, so a closure may move it alone), but the
  // tracker placed the next scan by the map, not by it: the motion across it keeps its weight.
  if (n >= 2 && nodes_[n - 1].own_weak)
    edges_.push_back(odometryEdge(n - 2, n, nodes_[n - 2].own_weak || nodes_[n - 1].weak_before || nodes_[n].weak()));
}

bool GraphSlam::weakEdge(int to) const { return nodes_[to].weak() || nodes_[to - 1].own_weak; }

bool GraphSlam::isNewNode(const Pose2D& tracker_pose) const {
  if (nodes_.empty()) return true;
  const Pose2D& last = nodes_.back().tracker_pose;
  return std::hypot(tracker_pose.x - last.x, tracker_pose.y - last.y) >= params_.graph.node_distance ||
         std::abs(Pose2D::normalizeAngle(tracker_pose.yaw - last.yaw)) >= params_.graph.node_angle;
}

Submap& GraphSlam::activeSubmap() { return *submaps_.back(); }

Pose2D GraphSlam::trackedInAnchor(const Submap& submap, int node) const {
  return nodes_[submap.anchor()].tracker_pose.inverse().compose(nodes_[node].tracker_pose);
}

Pose2D GraphSlam::optimizedInAnchor(const Submap& submap, int node) const {
  return poses_[submap.anchor()].inverse().compose(poses_[node]);
}

void GraphSlam::followOptimizedPoses() {
  const double xy = params_.graph.redraw_xy, yaw = params_.graph.redraw_yaw;
  if (!(xy > 0) || !(yaw > 0)) return;
  for (auto& submap_ptr : submaps_) {
    Submap& submap = *submap_ptr;
    std::vector<Pose2D> node_poses;
    node_poses.reserve(submap.nodeList().size());
    for (const auto& entry : submap.nodeList()) node_poses.push_back(optimizedInAnchor(submap, entry.first));
    if (submap.follow(node_poses, xy, yaw)) ++stats_.submaps_redrawn;
  }
}

void GraphSlam::addNode(const LaserScan& scan, const Pose2D& tracker_pose, bool weak_before, bool own_weak,
                        ScanStep& step) {
  const int n = static_cast<int>(nodes_.size());
  Node node{tracker_pose, travel_, thinPoints(scanPoints(scan, tracker_.laserInBase()), params_.graph.loop_resolution)};
  if (n == 0) {
    poses_.push_back(tracker_pose);
  } else {
    const Pose2D motion = nodes_.back().tracker_pose.inverse().compose(tracker_pose);
    poses_.push_back(poses_.back().compose(motion));
  }
  // The first node is the map's origin: nothing to match it against, nothing off.
  node.weak_before = n > 0 && weak_before;
  node.own_weak = n > 0 && own_weak;
  nodes_.push_back(std::move(node));
  addTrackerEdges(n);
  weak_since_node_ = false;
  int finished = -1;
  if (submaps_.empty() || activeSubmap().finished() || activeSubmap().nodes() >= params_.graph.submap_nodes) {
    if (!submaps_.empty() && !activeSubmap().finished())
      activeSubmap().finish(travel_), finished = static_cast<int>(submaps_.size()) - 1;
    submaps_.push_back(std::make_unique<Submap>(n, params_.grid, tracker_.laserInBase(), params_.graph.loop_resolution));
    ++stats_.submaps;
  }
  activeSubmap().addNode(n, trackedInAnchor(activeSubmap(), n));
  ++stats_.nodes;
  step.new_node = true;
  if (params_.loop_closure) closeLoops(n, step);
  if (params_.loop_closure && params_.graph.loop_older_nodes && finished >= 0) closeLoopsOfOlderNodes(finished, step);
  if (unoptimized_closures_ > 0 && ++nodes_since_optimization_ >= params_.graph.optimize_every)
    step.map_moved = optimize() || step.map_moved;
}

void GraphSlam::closeLoops(int n, ScanStep& step) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<Pose2D> anchor_poses;
  anchor_poses.reserve(submaps_.size());
  for (const auto& s : submaps_) anchor_poses.push_back(poses_[s->anchor()]);
  const LoopQuery query{nodes_[n].points, poses_[n], travel_,
                        graphDistances(static_cast<int>(nodes_.size()), edges_, n, loopLength(), closer_.saturationDistance())};
  std::vector<std::pair<int, LoopClosure>> found;
  for (const LoopClosure& c : closer_.search(query, submaps_, anchor_poses, stats_)) found.emplace_back(n, c);
  stats_.loop_search_ms += msSince(start);
  expirePending();
  addClosures(found, step);
}

void GraphSlam::closeLoopsOfOlderNodes(int index, ScanStep& step) {
  const auto start = std::chrono::steady_clock::now();
  const Submap& submap = *submaps_[index];
  std::vector<int> members;
  for (const auto& [node, pose] : submap.nodeList()) members.push_back(node);
  const std::vector<double> distance =
      graphDistances(static_cast<int>(nodes_.size()), edges_, members, loopLength(), closer_.saturationDistance());
  // Nodes near one a closure already ties to this submap are not searched again: the forward
  // search found that stretch from the submap's side.
  std::vector<char> tied(nodes_.size(), 0);
  for (const PoseGraphEdge& e : edges_)
    if (e.loop_closure && e.to >= members.front() && e.to <= members.back())
      for (int k = std::max(0, e.from - kTiedNeighbours); k <= std::min(e.from + kTiedNeighbours, members.front() - 1); ++k)
        tied[static_cast<size_t>(k)] = 1;
  const std::vector<char> lone = loneNodes();
  const std::pair<double, double> lone_window{params_.graph.loop_lone_window_xy, params_.graph.loop_lone_window_yaw};
  const Pose2D& anchor_pose = poses_[submap.anchor()];
  const double newest_travel = nodes_[submap.anchor()].travel - params_.graph.loop_min_travel;
  std::vector<std::pair<int, LoopClosure>> found;
  for (int m = 0; m < submap.anchor() && nodes_[m].travel <= newest_travel; ++m) {
    // Only nodes among the submap's own poses (within the window, no view distance): every old
    // node near enough to see part of it would cost as much again as the forward search.
    const auto window = closer_.window(distance[m]);
    if (tied[static_cast<size_t>(m)] || closer_.beyond(submap, anchor_pose, poses_[m]) > window.first) continue;
    if (auto c = closer_.tryClosure(nodes_[m].points, poses_[m], index, submap, anchor_pose,
                                    lone[static_cast<size_t>(m)] ? lone_window : window, stats_))
      found.emplace_back(m, *c);
  }
  // New nodes reach this submap only loop_min_travel later: its grids need not stay in memory
  // beside the older submaps' until then (ACES peaked 11 MB higher, over 300 MB, with them kept).
  closer_.forget(index);
  stats_.loop_search_ms += msSince(start);
  addClosures(found, step);
}

void GraphSlam::addClosures(const std::vector<std::pair<int, LoopClosure>>& found, ScanStep& step) {
  int accepted = 0;
  const std::vector<char> lone = found.empty() ? std::vector<char>{} : loneNodes();
  for (const auto& [node, c] : found) {
    // Relative to the submap's node nearest to the match: the submap holds the tracker's drift
    // since its anchor, the nearest node only what drifted between it and the match.
    const auto& [near, near_in_anchor] = submaps_[c.submap]->nearestNode(c.pose.x, c.pose.y);
    const Closure closure{near, node, near_in_anchor.inverse().compose(c.pose), nodes_[node].travel, travel_,
                          lone[static_cast<size_t>(node)] != 0};
    for (const Closure& confirmed : admit(closure)) {
      edges_.push_back(loopEdge(confirmed.from, confirmed.to, confirmed.measurement));
      ++accepted;
    }
  }
  if (accepted > 0) {
    stats_.loop_accepted += accepted;
    step.loop_closures += accepted;
    // Closures the graph already agrees with can wait: the graph is optimised when one
    // disagrees, or every optimize_every nodes (and by finish()).
    double worst = 0;
    for (size_t i = edges_.size() - accepted; i < edges_.size(); ++i) worst = std::max(worst, edgeChi2(poses_, edges_[i]));
    unoptimized_closures_ += accepted;
    if (worst > params_.graph.optimize_chi2) step.map_moved = optimize() || step.map_moved;
  }
}

std::vector<char> GraphSlam::loneNodes() const {
  std::vector<char> lone(nodes_.size(), 0);
  for (size_t k = 1; k < nodes_.size(); ++k)
    if (nodes_[k].weak()) lone[k - 1] = lone[k] = 1;
  for (const PoseGraphEdge& e : edges_)
    if (e.loop_closure) lone[static_cast<size_t>(e.from)] = lone[static_cast<size_t>(e.to)] = 0;
  return lone;
}

double GraphSlam::loopLength() const {
  return params_.graph.loop_sigma_xy / std::max(1e-6, params_.graph.loop_window_xy_per_m);
}

void GraphSlam::finish() {
  // No scan follows: the active submap is as complete as it will get. Its older nodes are
  // searched now, as they would have been when the next submap began; otherwise the end of a
  // run is the one stretch never matched from the other side (ACES every 5th scan, phase 2:
  // 0.69 -> 0.47 m). A scan that does come starts a new submap.
  if (params_.loop_closure && params_.graph.loop_older_nodes && !submaps_.empty() && !activeSubmap().finished() &&
      activeSubmap().nodes() > 1) {
    ScanStep step;
    activeSubmap().finish(travel_);
    closeLoopsOfOlderNodes(static_cast<int>(submaps_.size()) - 1, step);
  }
  if (unoptimized_closures_ > 0) optimize();
  // No scan follows: the search grids would only add to the peak of composing and writing the
  // map (Freiburg campus: 36 MB), and of the refinement. A scan that does come builds them again.
  closer_.releaseCache();
  tracker_.releaseSearchGrids();
  reanchorStretches();
  refineNodes();
}

std::vector<const Points2*> GraphSlam::nodeScans() const {
  std::vector<const Points2*> scans;
  scans.reserve(nodes_.size());
  for (const Node& node : nodes_) scans.push_back(&node.points);
  return scans;
}

void GraphSlam::reanchorStretches() {
  if (params_.graph.reanchor_max_nodes < 1) return;
  StretchReanchorParams reanchor;
  reanchor.max_nodes = static_cast<size_t>(params_.graph.reanchor_max_nodes);
  reanchor.min_turn = params_.graph.reanchor_min_turn;
  reanchor.min_gain = params_.graph.reanchor_min_gain;
  const std::vector<const Points2*> scans = nodeScans();
  const auto n = static_cast<int>(nodes_.size());
  bool moved = false;
  for (const int split : doubted_splits_) {
    if (split < 1 || split >= n) continue;
    // A closure between the stretches already holds them together where the graph has them.
    const bool tied = std::any_of(edges_.begin(), edges_.end(), [split](const PoseGraphEdge& e) {
      return e.loop_closure && std::min(e.from, e.to) < split && std::max(e.from, e.to) >= split;
    });
    if (tied) continue;
    const auto turn = reanchorStretch(scans, poses_, static_cast<size_t>(split), reanchor);
    if (!turn) continue;
    for (int k = split; k < n; ++k) poses_[k] = turn->compose(poses_[k]);
    // The tracker's motion across the split becomes what the scans say, so that a later
    // optimisation keeps the stretches where they now are.
    for (PoseGraphEdge& e : edges_)
      if (!e.loop_closure && e.from < split && e.to >= split) e.measurement = poses_[e.from].inverse().compose(poses_[e.to]);
    ++stats_.stretches_reanchored;
    moved = true;
  }
  doubted_splits_.clear();
  if (!moved) return;
  followOptimizedPoses();
  ++map_version_;
}

void GraphSlam::refineNodes() {
  NodeRefinementParams refinement;
  refinement.rounds = params_.graph.refine_rounds;
  refinement.max_rounds = params_.graph.refine_max_rounds;
  refinement.node_rounds = params_.graph.refine_node_rounds;
  refinement.settled_rms = params_.graph.refine_settled_rms;
  refinement.max_correspondence = params_.graph.refine_max_correspondence;
  refinement.min_correspondence = params_.matcher.min_correspondence;
  refinement.min_goodness = params_.graph.refine_min_goodness;
  refinement.correspondence_points = params_.matcher.correspondence_points;
  refinement.reseat_xy = params_.graph.refine_reseat_xy;
  refinement.reseat_yaw = params_.graph.refine_reseat_yaw;
  refinement.reseat_margin = params_.graph.refine_reseat_margin;
  refinement.grid_resolution = params_.seed.resolution;
  refinement.grid_sigma = params_.seed.sigma;
  refinement.reseat_min_points = params_.seed.overrule_min_points;
  refinement.joint_solves = params_.graph.refine_joint_solves;
  refinement.joint.reach = params_.graph.refine_joint_reach;
  refinement.joint.huber = params_.graph.refine_joint_huber;
  refinement.joint.points_per_node = params_.graph.refine_joint_points;
  refinement.joint.min_goodness = params_.graph.refine_min_goodness;
  if (refinement.rounds < 1 || nodes_.size() < 2) return;
  RefinedPoses refined = refineNodePoses(nodeScans(), poses_, refinement);
  // The poses leave the graph's optimum: a scan that comes after this continues from them, and
  // the next optimisation starts from them and returns to the graph's optimum.
  poses_ = std::move(refined.poses);
  stats_.nodes_refined = refined.moved;
  stats_.refine_rounds = refined.rounds;
  stats_.nodes_reseated = refined.reseated;
  followOptimizedPoses();
  ++map_version_;
}

bool GraphSlam::agreesWithGraph(const Closure& c) const {
  const Pose2D predicted = poses_[c.from].inverse().compose(poses_[c.to]);
  const Pose2D correction = predicted.inverse().compose(c.measurement);
  return std::hypot(correction.x, correction.y) <= params_.graph.loop_confirm_xy &&
         std::abs(correction.yaw) <= params_.graph.loop_confirm_yaw;
}

bool GraphSlam::consistent(const Closure& a, const Closure& b) const {
  // Only an independent view confirms: the node after a wrong match sees the same stretch of
  // corridor and is fooled the same way (ACES started 3 scans in: two nodes a metre apart
  // agreed on a pose 5 m along a corridor).
  if (std::abs(b.travel - a.travel) < params_.graph.loop_consistency_min_travel) return false;
  // Where each closure puts its node in the map frame; the tracker's motion between the two
  // nodes must join those places.
  const Pose2D a_to = poses_[a.from].compose(a.measurement);
  const Pose2D b_to = poses_[b.from].compose(b.measurement);
  const Pose2D motion = nodes_[a.to].tracker_pose.inverse().compose(nodes_[b.to].tracker_pose);
  const Pose2D gap = a_to.compose(motion).inverse().compose(b_to);
  // A lone node's closure may be the first to say where a stretch the tracker lost really lies:
  // its partner, across that stretch, is held only to what the weak edges between them allow.
  const bool across_lost = (a.lone || b.lone) && params_.graph.loop_consistency_weak_sigmas > 0;
  const auto [extra_xy, extra_yaw] = across_lost ? weakMotionSlack(a.to, b.to) : std::pair<double, double>{0, 0};
  return std::hypot(gap.x, gap.y) <= params_.graph.loop_consistency_xy + extra_xy &&
         std::abs(gap.yaw) <= params_.graph.loop_consistency_yaw + extra_yaw;
}

std::pair<double, double> GraphSlam::weakMotionSlack(int a, int b) const {
  double var_xy = 0, var_yaw = 0, length = 0;
  for (int k = std::min(a, b) + 1; k <= std::max(a, b); ++k) {
    const PoseGraphEdge e = odometryEdge(k - 1, k, true);
    length += std::hypot(e.measurement.x, e.measurement.y);
    if (!nodes_[k].weak()) continue;
    var_xy += 1 / e.information(0, 0);
    var_yaw += 1 / e.information(2, 2);
  }
  const double sd_yaw = std::sqrt(var_yaw);
  // Never more than the lone window: the weak edges' sigmas (weak_edge_factor times the usual)
  // grow past any error a search could have found.
  const double sigmas = params_.graph.loop_consistency_weak_sigmas;
  return {std::min(params_.graph.loop_lone_window_xy, sigmas * (std::sqrt(var_xy) + sd_yaw * length)),
          std::min(params_.graph.loop_lone_window_yaw, sigmas * sd_yaw)};
}

std::vector<GraphSlam::Closure> GraphSlam::admit(const Closure& c) {
  // A closure close to what the graph already believes is accepted; one that would move the
  // graph a lot waits for a second closure that agrees with it (a wrong match in a corridor or a
  // repeated room rarely finds a consistent partner).
  if (agreesWithGraph(c)) return {c};
  for (auto it = pending_.begin(); it != pending_.end(); ++it)
    if (consistent(*it, c)) {
      std::vector<Closure> both{*it, c};
      pending_.erase(it);
      return both;
    }
  pending_.push_back(c);
  ++stats_.loop_pending;
  return {};
}

void GraphSlam::expirePending() {
  const size_t before = pending_.size();
  pending_.erase(std::remove_if(pending_.begin(), pending_.end(),
                                [&](const Closure& c) { return travel_ - c.found_at > params_.graph.loop_confirm_travel; }),
                 pending_.end());
  stats_.loop_unconfirmed += before - pending_.size();
}

void GraphSlam::addLoopClosure(int from_node, int to_node, const Pose2D& measurement) {
  edges_.push_back(loopEdge(from_node, to_node, measurement));
  ++stats_.loop_accepted;
  optimize();
}

PoseGraphEdge GraphSlam::odometryEdge(int from, int to, bool weak) const {
  const GraphParams& g = params_.graph;
  const Pose2D motion = nodes_[from].tracker_pose.inverse().compose(nodes_[to].tracker_pose);
  const double d = std::hypot(motion.x, motion.y), turn = std::abs(motion.yaw);
  // A stretch the tracker did not match well (or where the odometry jumped or slipped) may be
  // wrong: loop closures must be able to bend it.
  const double scale = weak ? g.weak_edge_factor : 1.0;
  const double sxy = scale * (g.odometry_sigma_xy + g.odometry_sigma_xy_per_m * d);
  const double syaw = scale * (g.odometry_sigma_yaw + g.odometry_sigma_yaw_per_m * d + g.odometry_sigma_yaw_per_rad * turn);
  PoseGraphEdge e;
  e.from = from, e.to = to, e.measurement = motion;
  // Loop-closure windows through such a stretch grow as fast as its sigmas: after a lost
  // track, closures can reach the pose where the scans really were.
  e.drift_factor = scale;
  e.information = Eigen::Vector3d(1 / (sxy * sxy), 1 / (sxy * sxy), 1 / (syaw * syaw)).asDiagonal();
  return e;
}

PoseGraphEdge GraphSlam::loopEdge(int from, int to, const Pose2D& measurement) const {
  const GraphParams& g = params_.graph;
  PoseGraphEdge e;
  e.from = from, e.to = to, e.measurement = measurement, e.loop_closure = true;
  e.information = Eigen::Vector3d(1 / (g.loop_sigma_xy * g.loop_sigma_xy), 1 / (g.loop_sigma_xy * g.loop_sigma_xy),
                                  1 / (g.loop_sigma_yaw * g.loop_sigma_yaw)).asDiagonal();
  return e;
}

bool GraphSlam::optimize() {
  bool moved = false;
  unoptimized_closures_ = 0;
  nodes_since_optimization_ = 0;
  for (int round = 0; round < kMaxOutlierRounds; ++round) {
    ++stats_.optimizations;
    const OptimizeResult result = solver_->optimize(poses_, edges_);
    stats_.optimization_ms += result.milliseconds;
    if (!result.ok) {
      ++stats_.optimization_failures;
      stats_.last_problem = "pose graph not optimised, last good poses kept: " + result.reason;
      return moved;
    }
    moved = true;
    const size_t before = edges_.size();
    edges_.erase(std::remove_if(edges_.begin(), edges_.end(),
                                [&](const PoseGraphEdge& e) {
                                  return e.loop_closure && edgeChi2(poses_, e) > params_.graph.loop_outlier_chi2;
                                }),
                 edges_.end());
    stats_.loop_dropped += before - edges_.size();
    if (edges_.size() == before) break;
  }
  followOptimizedPoses();
  ++map_version_;
  return moved;
}

Pose2D GraphSlam::pose() const {
  if (nodes_.empty()) return tracker_.filter().pose();
  return poses_.back().compose(nodes_.back().tracker_pose.inverse().compose(tracker_.filter().pose()));
}

std::vector<Pose2D> GraphSlam::trajectory() const {
  std::vector<Pose2D> out;
  out.reserve(scans_.size());
  for (const ScanRef& s : scans_) out.push_back(poses_[s.node].compose(s.offset));
  return out;
}

std::vector<MapPart> GraphSlam::mapParts() const {
  // The first submap's anchor is node 0, which the optimiser holds at the map frame's origin.
  std::vector<MapPart> parts;
  for (const auto& s : submaps_) parts.push_back(s->part(poses_[s->anchor()]));
  return parts;
}

std::unique_ptr<FrontEnd> makeFrontEnd(const RobotSlamParams& params, const Pose2D& laser_in_base) {
  if (params.loop_closure) return std::make_unique<GraphSlam>(params, laser_in_base);
  return std::make_unique<EkfFrontEnd>(params, laser_in_base);
}

}  // namespace mrslam::slam
