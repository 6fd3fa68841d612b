#include "mrslam/slam/robot_params.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace mrslam::slam {

std::vector<NamedParam> robotSlamParams(RobotSlamParams& p) {
  MotionNoise& m = p.motion;
  ScanMatcherParams& s = p.matcher;
  GridMapperParams& g = p.grid;
  SeedParams& seed = p.seed;
  GraphParams& graph = p.graph;
  return {
      {"odom_trans_per_trans", &m.trans_per_trans},
      {"odom_trans_per_rot", &m.trans_per_rot},
      {"odom_rot_per_trans", &m.rot_per_trans},
      {"odom_rot_per_rot", &m.rot_per_rot},
      {"odom_floor_trans", &m.floor_trans},
      {"odom_floor_rot", &m.floor_rot},
      {"max_odometry_jump", &p.max_odometry_jump},
      {"max_odometry_speed", &p.max_odometry_speed},
      {"odometry_stride_factor", &p.odometry_stride_factor},
      {"no_odometry_sigma_xy", &p.no_odometry_sigma_xy},
      {"no_odometry_sigma_yaw", &p.no_odometry_sigma_yaw},
      {"no_odometry_max_xy", &p.no_odometry_max_xy},
      {"no_odometry_max_yaw", &p.no_odometry_max_yaw},
      {"use_scan_matching", &p.use_scan_matching},
      {"use_imu", &p.use_imu},
      {"imu_check_turns", &p.gyro_check.turns},
      {"imu_check_min_turn", &p.gyro_check.min_turn},
      {"imu_check_max_ratio", &p.gyro_check.max_ratio},
      {"icp_keyframes", &s.keyframes},
      {"icp_keyframe_distance", &s.keyframe_distance},
      {"icp_keyframe_angle", &s.keyframe_angle},
      {"icp_max_correspondence", &s.max_correspondence},
      {"icp_min_correspondence", &s.min_correspondence},
      {"icp_max_iterations", &s.max_iterations},
      {"icp_min_point_spacing", &s.min_point_spacing},
      {"icp_correspondence_points", &s.correspondence_points},
      {"icp_min_goodness", &s.min_goodness},
      {"icp_min_sigma_xy", &s.min_sigma_xy},
      {"icp_min_sigma_yaw", &s.min_sigma_yaw},
      {"icp_covariance_scale", &s.covariance_scale},
      {"map_resolution", &g.resolution},
      {"map_initial_size", &g.initial_size},
      {"map_max_insert_range", &g.max_insert_range},
      {"map_no_return_range", &g.no_return_range},
      {"map_occupied_update", &g.occupied_update},
      {"map_free_update", &g.free_update},
      {"map_update_distance", &p.map_update_distance},
      {"map_update_angle", &p.map_update_angle},
      {"seed_enabled", &seed.enabled},
      {"seed_min_sigma_xy", &seed.min_sigma_xy},
      {"seed_min_sigma_yaw", &seed.min_sigma_yaw},
      {"seed_window_sigmas", &seed.window_sigmas},
      {"seed_max_xy", &seed.max_xy},
      {"seed_max_yaw", &seed.max_yaw},
      {"seed_min_yaw", &seed.min_yaw},
      {"seed_min_yaw_below_score", &seed.min_yaw_below_score},
      {"seed_lost_below_score", &seed.lost_below_score},
      {"seed_min_score", &seed.min_score},
      {"seed_penalty_gain", &seed.penalty_gain},
      {"seed_min_penalty", &seed.min_penalty},
      {"seed_prior_sigma_xy", &seed.prior_sigma_xy},
      {"seed_prior_sigma_xy_per_m", &seed.prior_sigma_xy_per_m},
      {"seed_prior_sigma_yaw", &seed.prior_sigma_yaw},
      {"seed_prior_sigma_yaw_per_m", &seed.prior_sigma_yaw_per_m},
      {"seed_prior_sigma_yaw_per_rad", &seed.prior_sigma_yaw_per_rad},
      {"seed_prior_sigma_along", &seed.prior_sigma_along},
      {"seed_prior_sigma_along_per_m", &seed.prior_sigma_along_per_m},
      {"seed_min_penalty_along", &seed.min_penalty_along},
      {"seed_jump_margin", &seed.jump_margin},
      {"seed_jump_min_score", &seed.jump_min_score},
      {"seed_missed_turn_min_score", &seed.missed_turn_min_score},
      {"seed_missed_turn_max_rival", &seed.missed_turn_max_rival},
      {"seed_slip_margin", &seed.slip_margin},
      {"seed_reverse_margin", &seed.reverse_margin},
      {"seed_reverse_max_distance", &seed.reverse_max_distance},
      {"seed_reverse_max_reach_share", &seed.reverse_max_reach_share},
      {"seed_resolution", &seed.resolution},
      {"seed_sigma", &seed.sigma},
      {"seed_local_path", &seed.local_path},
      {"seed_icp_correspondence", &seed.icp_correspondence},
      {"seed_confirm_xy", &seed.confirm_xy},
      {"seed_confirm_yaw", &seed.confirm_yaw},
      {"seed_confirmed_min_goodness", &seed.confirmed_min_goodness},
      {"seed_alone_margin", &seed.alone_margin},
      {"seed_alone_sigma_xy", &seed.alone_sigma_xy},
      {"seed_alone_sigma_yaw", &seed.alone_sigma_yaw},
      {"seed_overrule_min_points", &seed.overrule_min_points},
      {"odometry_calibration", &p.odometry_calibration.enabled},
      {"odometry_calibration_forgetting", &p.odometry_calibration.forgetting},
      {"odometry_calibration_min_distance", &p.odometry_calibration.min_distance},
      {"odometry_calibration_max_scale_error", &p.odometry_calibration.max_scale_error},
      {"odometry_calibration_max_yaw_per_m", &p.odometry_calibration.max_yaw_per_m},
      {"odometry_calibration_from_seeds", &p.odometry_calibration.from_seeds},
      {"loop_closure", &p.loop_closure},
      {"graph_node_distance", &graph.node_distance},
      {"graph_node_angle", &graph.node_angle},
      {"graph_submap_nodes", &graph.submap_nodes},
      {"graph_redraw_xy", &graph.redraw_xy},
      {"graph_redraw_yaw", &graph.redraw_yaw},
      {"graph_odometry_sigma_xy", &graph.odometry_sigma_xy},
      {"graph_odometry_sigma_xy_per_m", &graph.odometry_sigma_xy_per_m},
      {"graph_odometry_sigma_yaw", &graph.odometry_sigma_yaw},
      {"graph_odometry_sigma_yaw_per_m", &graph.odometry_sigma_yaw_per_m},
      {"graph_odometry_sigma_yaw_per_rad", &graph.odometry_sigma_yaw_per_rad},
      {"graph_weak_match_goodness", &graph.weak_match_goodness},
      {"graph_weak_edge_factor", &graph.weak_edge_factor},
      {"loop_min_travel", &graph.loop_min_travel},
      {"loop_window_xy", &graph.loop_window_xy},
      {"loop_window_xy_per_m", &graph.loop_window_xy_per_m},
      {"loop_window_xy_max", &graph.loop_window_xy_max},
      {"loop_window_yaw", &graph.loop_window_yaw},
      {"loop_window_yaw_per_m", &graph.loop_window_yaw_per_m},
      {"loop_window_yaw_max", &graph.loop_window_yaw_max},
      {"loop_max_candidates", &graph.loop_max_candidates},
      {"loop_matcher_cache_mb", &graph.loop_matcher_cache_mb},
      {"loop_view_distance", &graph.loop_view_distance},
      {"loop_older_nodes", &graph.loop_older_nodes},
      {"loop_lone_window_xy", &graph.loop_lone_window_xy},
      {"loop_lone_window_yaw", &graph.loop_lone_window_yaw},
      {"loop_resolution", &graph.loop_resolution},
      {"loop_sigma", &graph.loop_sigma},
      {"loop_min_score", &graph.loop_min_score},
      {"loop_max_rival", &graph.loop_max_rival},
      {"loop_sigma_xy", &graph.loop_sigma_xy},
      {"loop_sigma_yaw", &graph.loop_sigma_yaw},
      {"loop_confirm_xy", &graph.loop_confirm_xy},
      {"loop_confirm_yaw", &graph.loop_confirm_yaw},
      {"loop_consistency_xy", &graph.loop_consistency_xy},
      {"loop_consistency_yaw", &graph.loop_consistency_yaw},
      {"loop_consistency_min_travel", &graph.loop_consistency_min_travel},
      {"loop_consistency_weak_sigmas", &graph.loop_consistency_weak_sigmas},
      {"loop_confirm_travel", &graph.loop_confirm_travel},
      {"loop_outlier_chi2", &graph.loop_outlier_chi2},
      {"graph_optimize_chi2", &graph.optimize_chi2},
      {"graph_optimize_every", &graph.optimize_every},
      {"graph_solver", &graph.solver},
      {"graph_solver_iterations", &graph.solver_iterations},
      {"graph_refine_rounds", &graph.refine_rounds},
      {"graph_refine_max_rounds", &graph.refine_max_rounds},
      {"graph_refine_node_rounds", &graph.refine_node_rounds},
      {"graph_refine_settled_rms", &graph.refine_settled_rms},
      {"graph_refine_max_correspondence", &graph.refine_max_correspondence},
      {"graph_refine_min_goodness", &graph.refine_min_goodness},
      {"graph_refine_reseat_xy", &graph.refine_reseat_xy},
      {"graph_refine_reseat_yaw", &graph.refine_reseat_yaw},
      {"graph_refine_reseat_margin", &graph.refine_reseat_margin},
      {"graph_refine_joint_solves", &graph.refine_joint_solves},
      {"graph_refine_joint_reach", &graph.refine_joint_reach},
      {"graph_refine_joint_huber", &graph.refine_joint_huber},
      {"graph_refine_joint_points", &graph.refine_joint_points},
      {"graph_refine_reanchor_max_nodes", &graph.reanchor_max_nodes},
      {"graph_refine_reanchor_min_turn", &graph.reanchor_min_turn},
      {"graph_refine_reanchor_min_gain", &graph.reanchor_min_gain},
  };
}

const std::vector<std::string>& rosLayerParamNames() {
  static const std::vector<std::string> names = {
      "map_frame", "odom_frame", "base_frame", "publish_tf", "use_odometry", "transform_tolerance",
      "map_publish_rate", "max_time_jump", "restart_scans", "future_tolerance", "max_rays", "trajectory_max_poses",
      "input_owner_timeout", "imu_wait", "imu_max_gap", "gyro_noise_density", "gyro_residual_bias",
      "diagnostics_period"};
  return names;
}

namespace {

// Upper bounds of the parameters whose size sets how much memory or time a scan takes (search
// windows, kernels, map sizes) or which a formula needs below a limit; far above any working
// value, so that a typo (1e12 for 1.2) is refused instead of allocating or looping without end.
struct Limit {
  const char* name;
  double max;
  bool zero_allowed;  // false: must be above 0 (a divisor or a halving that must end)
};
const Limit kLimits[] = {
    {"map_resolution", 10.0, false},
    {"map_initial_size", 10000.0, false},
    {"map_max_insert_range", 1000.0, true},
    {"map_no_return_range", 300.0, true},
    {"map_occupied_update", 0.999, false},  // probabilities
    {"map_free_update", 0.999, false},
    {"icp_max_correspondence", 100.0, false},
    {"icp_min_correspondence", 100.0, false},
    {"seed_window_sigmas", 100.0, true},
    {"seed_max_xy", 50.0, true},
    {"seed_max_yaw", 3.15, true},  // rad
    {"seed_min_yaw", 3.15, true},
    {"loop_window_yaw", 3.15, true},
    {"loop_window_yaw_max", 3.15, true},
    {"loop_lone_window_yaw", 3.15, true},
    {"seed_resolution", 10.0, false},
    {"seed_sigma", 10.0, false},
    {"seed_local_path", 10000.0, true},
    {"loop_window_xy", 100.0, true},
    {"loop_window_xy_max", 100.0, true},
    {"loop_lone_window_xy", 100.0, true},
    {"loop_resolution", 10.0, false},
    {"loop_sigma", 10.0, false},
    {"loop_sigma_xy", 100.0, false},
    {"loop_sigma_yaw", 100.0, false},
    {"loop_matcher_cache_mb", 1e6, true},
    {"odometry_calibration_forgetting", 1.0, false},
    {"odometry_calibration_max_scale_error", 0.99, true},
    {"graph_weak_edge_factor", 1e6, false},
    {"graph_refine_rounds", 100.0, true},
    {"graph_refine_max_rounds", 1000.0, true},
    {"graph_refine_node_rounds", 1e7, true},
    {"graph_refine_settled_rms", 1.0, true},
    {"graph_refine_max_correspondence", 100.0, false},
    {"graph_refine_min_goodness", 1.0, true},
    {"graph_refine_reseat_xy", 10.0, true},
    {"graph_refine_reseat_yaw", 3.15, true},
    {"graph_refine_reseat_margin", 1.0, true},
    {"graph_refine_joint_solves", 100.0, true},
    {"graph_refine_joint_reach", 10.0, false},
    {"graph_refine_joint_huber", 10.0, false},
    {"graph_refine_joint_points", 100000.0, true},
    {"graph_refine_reanchor_max_nodes", 100000.0, true},
    {"graph_refine_reanchor_min_turn", 3.15, true},
    {"graph_refine_reanchor_min_gain", 1000.0, false},
    {"seed_overrule_min_points", 100000.0, true},
    {"imu_check_turns", 1000.0, true},
    {"imu_check_min_turn", 3.15, true},
    {"imu_check_max_ratio", 1000.0, false},
};

std::string number(double v) {
  std::ostringstream text;
  text << v;
  return text.str();
}

// What is wrong with one numeric parameter's value: every number must be finite and >= 0, and
// those of kLimits within their limits.
std::string rangeProblem(const NamedParam& named) {
  double v = 0;
  if (const auto* field = std::get_if<int*>(&named.field)) v = **field;
  else if (const auto* real = std::get_if<double*>(&named.field)) v = **real;
  else return "";  // not a number
  const Limit* limit = nullptr;
  for (const Limit& l : kLimits)
    if (named.name == l.name) limit = &l;
  const bool ok = std::isfinite(v) && v >= 0 && (!limit || (v <= limit->max && (limit->zero_allowed || v > 0)));
  if (ok) return "";
  const std::string range = !limit              ? "a finite number >= 0"
                            : limit->zero_allowed ? "within [0, " + number(limit->max) + "]"
                                                  : "within (0, " + number(limit->max) + "]";
  return named.name + " must be " + range + " (got " + number(v) + ")";
}

}  // namespace

std::string robotSlamParamsProblem(const RobotSlamParams& p) {
  RobotSlamParams copy = p;
  for (const NamedParam& named : robotSlamParams(copy)) {
    const std::string problem = rangeProblem(named);
    if (!problem.empty()) return problem;
  }
  if (p.matcher.keyframes < 1 || p.matcher.max_iterations < 1)
    return "icp_keyframes and icp_max_iterations must be >= 1";
  // ICP halves its pairing distance until it falls below the final one.
  if (!(p.matcher.max_correspondence >= p.matcher.min_correspondence))
    return "icp_min_correspondence must be at most icp_max_correspondence";
  if (!(p.graph.refine_max_correspondence >= p.matcher.min_correspondence))
    return "graph_refine_max_correspondence must be at least icp_min_correspondence";
  if (!(p.gyro_check.max_ratio >= 1)) return "imu_check_max_ratio must be at least 1 (got " + number(p.gyro_check.max_ratio) + ")";
  if (p.graph.solver != "ceres" && p.graph.solver != "mrpt")
    return "graph_solver must be ceres or mrpt (got '" + p.graph.solver + "')";
  return "";
}

RobotSlamParams loadRobotSlamParams(const std::string& yaml_path) {
  const auto& ignored = rosLayerParamNames();
  YAML::Node root;
  try {
    root = YAML::LoadFile(yaml_path);
  } catch (const std::exception& e) {
    throw RobotParamsError(yaml_path + ": " + e.what());
  }
  RobotSlamParams p;
  if (root.IsNull()) return p;
  if (!root.IsMap()) throw RobotParamsError(yaml_path + ": expected a map of parameters");
  auto named = robotSlamParams(p);
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    if (std::find(ignored.begin(), ignored.end(), key) != ignored.end()) continue;
    auto it = std::find_if(named.begin(), named.end(), [&](const NamedParam& n) { return n.name == key; });
    if (it == named.end()) throw RobotParamsError(yaml_path + ": unknown parameter '" + key + "'");
    try {
      std::visit([&](auto* field) { *field = kv.second.as<std::remove_pointer_t<decltype(field)>>(); }, it->field);
    } catch (const std::exception&) {
      throw RobotParamsError(yaml_path + ": bad value for '" + key + "'");
    }
  }
  const std::string problem = robotSlamParamsProblem(p);
  if (!problem.empty()) throw RobotParamsError(yaml_path + ": " + problem);
  return p;
}

}  // namespace mrslam::slam
