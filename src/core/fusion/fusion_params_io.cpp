#include "mrslam/fusion/fusion_params_io.h"

#include <yaml-cpp/yaml.h>

#include <functional>
#include <map>

namespace mrslam::fusion {
namespace {

using Setter = std::function<void(const YAML::Node&)>;

template <typename T>
Setter bind(T& field) {
  return [&field](const YAML::Node& n) { field = n.as<T>(); };
}

}  // namespace

FusionParams loadFusionParams(const std::string& yaml_path) {
  FusionParams p;
  SegmentMatchingParams& s = p.segments;
  VerificationParams& v = p.verification;
  const std::map<std::string, Setter> setters = {
      {"occupied_threshold", bind(p.occupied_threshold)},
      {"free_threshold", bind(p.free_threshold)},
      {"seed", bind(p.seed)},
      {"use_segments", bind(p.use_segments)},
      {"segment_max_cells", bind(p.segment_max_cells)},
      {"canny_blur_sigma", bind(s.canny.blur_sigma)},
      {"canny_low_threshold", bind(s.canny.low_threshold)},
      {"canny_high_threshold", bind(s.canny.high_threshold)},
      {"smoothing_distance", bind(s.smoothing_distance)},
      {"segment_points", bind(s.segment.points)},
      {"distance_bins", bind(s.segment.distance_bins)},
      {"arc_bins", bind(s.segment.arc_bins)},
      {"h_d", bind(s.segment.h_d)},
      {"omega_c", bind(s.segment.omega_c)},
      {"segment_trials", bind(s.trials)},
      {"segment_min_correlation", bind(s.min_correlation)},
      {"segment_max_pairs", bind(s.max_pairs)},
      {"spectrum_max_cells", bind(p.spectrum_max_cells)},
      {"spectrum_step_deg", bind(p.spectrum_step_deg)},
      {"rotation_candidates", bind(p.rotation_candidates)},
      {"coarse_max_cells", bind(p.coarse_max_cells)},
      {"translation_peaks", bind(p.translation_peaks)},
      {"fourier_max_cells", bind(p.fourier_max_cells)},
      {"coarse_search_radius", bind(p.coarse_search_radius)},
      {"segment_search_radius", bind(p.segment_search_radius)},
      {"coarse_rotation_step_deg", bind(p.coarse_rotation_step_deg)},
      {"coarse_rotation_steps", bind(p.coarse_rotation_steps)},
      {"refined_hypotheses", bind(p.refined_hypotheses)},
      {"radon_window_deg", bind(p.radon_window_deg)},
      {"radon_step_deg", bind(p.radon_step_deg)},
      {"radon_peaks", bind(p.radon_peaks)},
      {"refine_radius", bind(p.refine_radius)},
      {"chamfer_polish", bind(p.chamfer_polish)},
      {"chamfer_truncation", bind(p.chamfer_truncation)},
      {"max_free_points", bind(p.max_free_points)},
      {"disagreement_weight", bind(p.disagreement_weight)},
      {"retry_finer", bind(p.retry_finer)},
      {"retry_rotation_candidates", bind(p.retry_rotation_candidates)},
      {"max_resolution_ratio", bind(p.max_resolution_ratio)},
      {"min_acceptance", bind(v.min_acceptance)},
      {"min_wall_agreement", bind(v.min_wall_agreement)},
      {"min_shared_wall_m", bind(v.min_shared_wall_m)},
      {"min_shared_wall_fraction", bind(v.min_shared_wall_fraction)},
      {"max_entropy_increase", bind(v.max_entropy_increase)},
      {"min_distinctiveness", bind(v.min_distinctiveness)},
      {"distinct_shift_m", bind(v.distinct_shift_m)},
      {"distinct_turn_deg", bind(v.distinct_turn_deg)},
      {"max_ambiguity", bind(v.max_ambiguity)},
  };
  YAML::Node root;
  try {
    root = YAML::LoadFile(yaml_path);
  } catch (const YAML::BadFile&) {
    throw ParamsError(yaml_path + ": cannot read file");
  } catch (const YAML::Exception& e) {
    throw ParamsError(yaml_path + ": malformed yaml: " + e.what());
  }
  if (root.IsNull()) return p;
  if (!root.IsMap()) throw ParamsError(yaml_path + ": expected a mapping of parameter: value");
  for (const auto& entry : root) {
    const std::string key = entry.first.as<std::string>();
    const auto it = setters.find(key);
    if (it == setters.end()) throw ParamsError(yaml_path + ": unknown parameter '" + key + "'");
    try {
      it->second(entry.second);
    } catch (const YAML::Exception&) {
      throw ParamsError(yaml_path + ": parameter '" + key + "' has an invalid value");
    }
  }
  if (p.segments.segment.points < 3 || p.segments.segment.distance_bins < 1 ||
      p.segments.segment.arc_bins < 1 || p.coarse_max_cells < 16 || p.fourier_max_cells < 16 || p.spectrum_max_cells < 16 ||
      p.refined_hypotheses < 1 || p.retry_finer < 0 || p.retry_rotation_candidates < 1 || p.rotation_candidates < 1 || p.translation_peaks < 1 ||
      !(p.spectrum_step_deg > 0) || !(p.radon_step_deg > 0) || !(p.max_resolution_ratio >= 1))
    throw ParamsError(yaml_path + ": a parameter is out of range (see config/fusion.yaml)");
  return p;
}

}  // namespace mrslam::fusion
