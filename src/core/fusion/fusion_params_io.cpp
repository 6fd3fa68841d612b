#include "mrslam/fusion/fusion_params_io.h"

#include <yaml-cpp/yaml.h>

#include <functional>
#include <map>
#include <sstream>

namespace mrslam::fusion {
namespace {

// One parameter: reads it from yaml, writes it back, and says why a value is out of range.
struct Field {
  std::function<void(const YAML::Node&)> read;
  std::function<std::string()> write;
  std::function<std::string()> range_problem;  // empty when the value is in range
};

template <typename T>
Field field(T& value, double low, double high) {
  return {[&value](const YAML::Node& n) { value = n.as<T>(); },
          [&value]() {
            std::ostringstream out;
            out.precision(17);
            if constexpr (std::is_same_v<T, bool>) out << (value ? "true" : "false");
            else out << value;
            return out.str();
          },
          [&value, low, high]() -> std::string {
            const double v = static_cast<double>(value);
            if (v >= low && v <= high) return "";
            std::ostringstream out;
            out << value << " is outside [" << low << ", " << high << "]";
            return out.str();
          }};
}
Field flag(bool& value) { return field(value, 0, 1); }

constexpr double kBig = 1e9;  // "no upper bound" for counts and sizes

// Every key of config/fusion.yaml, bound to its field, with the range it must lie in.
std::map<std::string, Field> fields(FusionParams& p) {
  SegmentMatchingParams& s = p.segments;
  VerificationParams& v = p.verification;
  return {
      {"occupied_threshold", field(p.occupied_threshold, 1, 100)},
      {"free_threshold", field(p.free_threshold, 0, 99)},
      {"seed", field(p.seed, 0, 4294967295.0)},
      {"use_segments", flag(p.use_segments)},
      {"segment_max_cells", field(p.segment_max_cells, 16, 100000)},
      {"canny_blur_sigma", field(s.canny.blur_sigma, 0, 100)},
      {"canny_low_threshold", field(s.canny.low_threshold, 0, 10000)},
      {"canny_high_threshold", field(s.canny.high_threshold, 0, 10000)},
      {"smoothing_distance", field(s.smoothing_distance, 0, 100)},
      {"segment_points", field(s.segment.points, 3, 10000)},
      {"distance_bins", field(s.segment.distance_bins, 1, 1000)},
      {"arc_bins", field(s.segment.arc_bins, 1, 1000)},
      {"h_d", field(s.segment.h_d, 0, kBig)},
      {"omega_c", field(s.segment.omega_c, 0, kBig)},
      {"segment_trials", field(s.trials, 0, 100000)},
      {"segment_min_correlation", field(s.min_correlation, -1, 1)},
      {"segment_max_pairs", field(s.max_pairs, 0, 10000)},
      {"spectrum_max_cells", field(p.spectrum_max_cells, 16, 100000)},
      {"spectrum_step_deg", field(p.spectrum_step_deg, 0.01, 45)},
      {"rotation_candidates", field(p.rotation_candidates, 1, 180)},
      {"coarse_max_cells", field(p.coarse_max_cells, 16, 100000)},
      {"translation_peaks", field(p.translation_peaks, 1, 1000)},
      {"fourier_max_cells", field(p.fourier_max_cells, 16, 100000)},
      {"coarse_search_radius", field(p.coarse_search_radius, 0, 1000)},
      {"segment_search_radius", field(p.segment_search_radius, 0, 1000)},
      {"coarse_rotation_step_deg", field(p.coarse_rotation_step_deg, 0.01, 45)},
      {"coarse_rotation_steps", field(p.coarse_rotation_steps, 0, 1000)},
      {"refined_hypotheses", field(p.refined_hypotheses, 1, 1000)},
      {"radon_window_deg", field(p.radon_window_deg, 0, 90)},
      {"radon_step_deg", field(p.radon_step_deg, 0.001, 45)},
      {"radon_peaks", field(p.radon_peaks, 1, 180)},
      {"refine_radius", field(p.refine_radius, 0, 1000)},
      {"chamfer_polish", flag(p.chamfer_polish)},
      {"chamfer_truncation", field(p.chamfer_truncation, 0.1, 8)},
      {"max_free_points", field(p.max_free_points, 0, kBig)},
      {"disagreement_weight", field(p.disagreement_weight, 0, kBig)},
      {"coarse_disagreement_weight", field(p.coarse_disagreement_weight, 0, kBig)},
      {"retry_finer", field(p.retry_finer, 0, 4)},
      {"retry_rotation_candidates", field(p.retry_rotation_candidates, 1, 180)},
      {"max_resolution_ratio", field(p.max_resolution_ratio, 1, 1000)},
      {"min_acceptance", field(v.min_acceptance, 0, 1)},
      {"min_wall_agreement", field(v.min_wall_agreement, 0, 1)},
      {"min_shared_wall_m", field(v.min_shared_wall_m, 0, kBig)},
      {"min_shared_wall_fraction", field(v.min_shared_wall_fraction, 0, 1)},
      {"max_entropy_increase", field(v.max_entropy_increase, 0, 2)},
      {"min_distinctiveness", field(v.min_distinctiveness, -kBig, 1)},
      {"distinct_shift_m", field(v.distinct_shift_m, 0, kBig)},
      {"distinct_turn_deg", field(v.distinct_turn_deg, 0, 180)},
      {"max_ambiguity", field(v.max_ambiguity, 0, kBig)},
      {"ambiguity_weight_factor", field(v.ambiguity_weight_factor, 1, kBig)},
      {"max_seen_through", field(v.max_seen_through, 0, 1)},
      {"max_lever", field(v.max_lever, 1, kBig)},
  };
}

}  // namespace

FusionParams loadFusionParams(const std::string& yaml_path) {
  FusionParams p;
  const std::map<std::string, Field> keys = fields(p);
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
    const auto it = keys.find(key);
    if (it == keys.end()) throw ParamsError(yaml_path + ": unknown parameter '" + key + "'");
    try {
      it->second.read(entry.second);
    } catch (const YAML::Exception&) {
      throw ParamsError(yaml_path + ": parameter '" + key + "' has an invalid value");
    }
    const std::string range = it->second.range_problem();
    if (!range.empty()) throw ParamsError(yaml_path + ": parameter '" + key + "' " + range);
  }
  return p;
}

std::map<std::string, std::string> fusionParamValues(const FusionParams& params) {
  FusionParams copy = params;
  std::map<std::string, std::string> out;
  for (const auto& [key, f] : fields(copy)) out[key] = f.write();
  return out;
}

}  // namespace mrslam::fusion
