#include "mrslam/slam/local_tracker.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <vector>

namespace mrslam::slam {
namespace {

// A turn the odometry may have missed, which the scan could not confirm (ScanStep::
// odometry_turn_doubted): the scan fits this many times better, and at least this well, at a
// heading at least this far from the odometry's. Below missed_turn_min_score such a fit is
// usually wrong (a corridor fits itself turned round), so it is only counted: on Seattle every
// 5th scan (a Radish log, not bundled) the odometry turned 0.6 degrees where the robot turned
// 80, the scan fitted 0.11 there and 0.165 turned round, and the map came out bent (6.7 m).
constexpr double kDoubtFitRatio = 3.0;
constexpr double kDoubtMinScore = 0.12;
constexpr double kDoubtMinTurn = M_PI / 4;

}  // namespace

LocalTracker::LocalTracker(const RobotSlamParams& params, const Pose2D& laser_in_base)
    : params_(params),
      laser_in_base_(laser_in_base),
      ekf_(params.motion),
      matcher_(params.matcher, laser_in_base),
      calibration_(params.odometry_calibration),
      gyro_check_(params.gyro_check) {
  reset();
}

void LocalTracker::reset() {
  // The map frame is the robot's pose at its first scan, known exactly.
  ekf_.reset(Pose2D{}, Eigen::Matrix3d::Identity() * 1e-9);
  matcher_.clear();
  releaseSearchGrids();
  calibration_.reset();
  odometry_ = Pose2D{};
  gyro_yaw_ = gyro_var_ = 0;
  have_gyro_ = false;
  gyro_check_.reset();
  strides_.clear();
  last_motion_ = Pose2D{};
  scans_ = 0;
}

void LocalTracker::addOdometry(const Pose2D& increment) {
  if (std::isfinite(increment.x) && std::isfinite(increment.y) && std::isfinite(increment.yaw))
    odometry_ = odometry_.compose(increment);
}

void LocalTracker::addGyro(double yaw_increment, double variance) {
  if (!std::isfinite(yaw_increment) || !std::isfinite(variance) || variance < 0) return;
  gyro_yaw_ += yaw_increment;
  gyro_var_ += variance;
  have_gyro_ = true;
}

// The increments a run has shown tell how far it moves between scans when time cannot: a slow
// scanner (a scan every 3-5 m) moves far further than max_odometry_jump every time, and judging
// each such increment against the previous pose drops real motion (the scan fits the part of
// the map it has already seen better at rest than where it drove into new ground). A jump of
// odometry (a reset, a glitch) is an outlier against the run's own strides; the high quantile
// of the last ones is not moved by one of them.
//
// Only strides of a moving robot count: standing or turning on the spot says nothing about how
// far it goes between scans when it drives (ACES stands for dozens of scans at a time, and the
// first metre after that was doubted). Until a few are known there is nothing to judge by
// (Intel every 5th scan starts 0.06, 0.04, then 4.15 m): odometry is taken as data.
constexpr size_t kStrideHistory = 50;
constexpr size_t kStrideWarmUp = 5;
constexpr double kStrideQuantile = 0.75;
constexpr double kMovingStride = 0.05;  // m
constexpr double kStoodStill = 0.1;     // m: an increment shorter than this says the robot stood

namespace {
// How far the scan sees: the range within which 95 % of its returns lie (base frame).
double reach(const Points2& points) {
  if (points.empty()) return 0.0;
  std::vector<double> ranges;
  ranges.reserve(points.size());
  for (const auto& [x, y] : points) ranges.push_back(std::hypot(x, y));
  const size_t k = (ranges.size() - 1) * 95 / 100;
  std::nth_element(ranges.begin(), ranges.begin() + k, ranges.end());
  return ranges[k];
}
}  // namespace

double LocalTracker::typicalStride() const {
  if (strides_.empty()) return 0.0;
  std::vector<double> sorted(strides_.begin(), strides_.end());
  const size_t k = static_cast<size_t>(kStrideQuantile * (sorted.size() - 1));
  std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
  return sorted[k];
}

void LocalTracker::rememberStride(const Pose2D& u) {
  const double length = std::hypot(u.x, u.y);
  if (length < kMovingStride) return;
  strides_.push_back(length);
  if (strides_.size() > kStrideHistory) strides_.pop_front();
}

bool LocalTracker::doubted(const Pose2D& u, double stamp) const {
  const double length = std::hypot(u.x, u.y), dt = stamp - last_stamp_;
  if (time_usable_ && dt > 0) return length > params_.max_odometry_jump + params_.max_odometry_speed * dt;
  // No time for this step: the log's stamps are unusable, or this one did not advance (stamps
  // rounded to whole seconds repeat now and then even where most differ).
  if (strides_.size() < kStrideWarmUp) return false;
  return length > std::max(params_.max_odometry_jump, params_.odometry_stride_factor * typicalStride());
}

const LikelihoodGrid& LocalTracker::seedGrid() {
  if (!seed_matcher_ || seed_version_ != matcher_.version()) {
    const SeedParams& sp = params_.seed;
    const Points2 local_map = matcher_.pointsWithinPath(sp.local_path);
    if (seed_matcher_) {  // in the buffers of the last one: rebuilt at nearly every key scan
      seed_grid_->rebuild(local_map, sp.resolution, sp.sigma, sp.max_xy);
      seed_matcher_->refresh();
    } else {
      seed_grid_ = std::make_shared<LikelihoodGrid>(local_map, sp.resolution, sp.sigma, sp.max_xy);
      seed_matcher_ = std::make_unique<CorrelativeMatcher>(seed_grid_, 5);
    }
    seed_version_ = matcher_.version();
  }
  return seed_matcher_->grid();
}

CorrelativeMatch LocalTracker::seedMatch(const Points2& points, const Pose2D& center, double xy, double yaw,
                                         const SeedPrior& prior, const Pose2D* rival_of, double rival_min_score) {
  seedGrid();  // brings seed_matcher_ up to date with the local map
  SearchWindow window{center, xy, yaw, prior.xy, prior.yaw, params_.seed.penalty_gain, params_.seed.min_penalty};
  window.sigma_along = prior.along;
  window.along_direction = prior.direction;
  window.min_penalty_along = params_.seed.min_penalty_along;
  const CorrelativeMatch match =
      rival_of ? seed_matcher_->match(points, window, rival_min_score, rival_of, CorrelativeMatcher::kRivalMinXy,
                                                  CorrelativeMatcher::kRivalMinYaw)
               : seed_matcher_->match(points, window, params_.seed.min_score);
  searches_given_up_ += match.exhausted;
  return match;
}

std::optional<CorrelativeMatch> LocalTracker::missedTurn(const Points2& points, const Pose2D& guess, double max_xy,
                                                         const SeedPrior& prior, double guess_fit, bool& doubted) {
  const SeedParams& sp = params_.seed;
  if (!(sp.missed_turn_min_score > 0)) return std::nullopt;  // off
  const CorrelativeMatch best = seedMatch(points, guess, max_xy, M_PI, prior);
  doubted = best.found && best.score >= kDoubtMinScore && best.score >= kDoubtFitRatio * guess_fit &&
            std::abs(Pose2D::normalizeAngle(best.pose.yaw - guess.yaw)) >= kDoubtMinTurn;
  if (!best.found || best.score < sp.missed_turn_min_score) return std::nullopt;
  // A fit below missed_turn_min_score was wrong on 63 of 69 steps of the bundled and nine other
  // Radish logs at every 3rd and 5th scan, 45 of them a corridor's reversal: a corridor fits
  // itself turned round about as well, so the pose must also stand well ahead of every other.
  const CorrelativeMatch rival = seedMatch(points, guess, max_xy, M_PI, prior, &best.pose, sp.missed_turn_max_rival * best.score);
  if (rival.found || rival.exhausted) return std::nullopt;
  doubted = false;  // overruled instead
  return best;
}

LocalTracker::SeedPrior LocalTracker::seedPrior(const Pose2D& before, const Pose2D& u) const {
  const SeedParams& sp = params_.seed;
  const double driven = std::hypot(u.x, u.y);
  SeedPrior prior;
  prior.xy = sp.prior_sigma_xy + sp.prior_sigma_xy_per_m * driven;
  prior.yaw = sp.prior_sigma_yaw + sp.prior_sigma_yaw_per_m * driven + sp.prior_sigma_yaw_per_rad * std::abs(u.yaw);
  // An increment shorter than two cells of the search grid has no direction worth the name.
  if (sp.prior_sigma_along > 0 && driven > 2 * sp.resolution) {
    prior.along = sp.prior_sigma_along + sp.prior_sigma_along_per_m * driven;
    prior.direction = before.yaw + std::atan2(u.y, u.x);
  }
  return prior;
}

Eigen::Matrix3d LocalTracker::noOdometryCovariance() const {
  const double xy = params_.no_odometry_sigma_xy, yaw = params_.no_odometry_sigma_yaw;
  return Eigen::Vector3d(xy * xy, xy * xy, yaw * yaw).asDiagonal();
}

// The constant-velocity guess knows no direction better than another: the prior is as wide as
// its uncertainty, so that the scan decides wherever it can.
LocalTracker::SeedPrior LocalTracker::noOdometryPrior() const {
  return {params_.no_odometry_sigma_xy, params_.no_odometry_sigma_yaw, 0.0, 0.0};
}

bool LocalTracker::seedConfirms(const ScanStep& step) const {
  const SeedParams& sp = params_.seed;
  const Pose2D moved = step.seed.inverse().compose(step.match.pose);
  return std::isfinite(step.match.pose.x) && step.match.covariance.allFinite() &&
         step.match.goodness >= sp.confirmed_min_goodness && std::hypot(moved.x, moved.y) <= sp.confirm_xy &&
         std::abs(moved.yaw) <= sp.confirm_yaw;
}

bool LocalTracker::seedStandsAlone(const ScanStep& step) const {
  return params_.seed.alone_margin > 0 && step.seed_score >= step.prediction_score + params_.seed.alone_margin;
}

bool LocalTracker::scanPrefers(const Points2& points, const Pose2D& match, const Pose2D& prediction) {
  if (!params_.seed.enabled) return false;
  const LikelihoodGrid& grid = seedGrid();
  return grid.score(transformPoints(points, match)) >
         grid.score(transformPoints(points, prediction)) + params_.seed.slip_margin;
}

std::optional<Pose2D> LocalTracker::reversedPrediction(const Points2& points, const Pose2D& before, const Pose2D& u) {
  const SeedParams& sp = params_.seed;
  // Shorter increments end within the likelihood kernel of the prediction: nothing to tell.
  const double driven = std::hypot(u.x, u.y);
  if (!sp.enabled || sp.reverse_margin <= 0 || driven < sp.resolution || driven > sp.reverse_max_distance)
    return std::nullopt;
  // Driven forwards, a scan sees ground the local map has not, and fits it worse than it fits
  // any mapped place behind: the bias grows with the increment against how far the laser sees.
  // Over the bundled and Radish logs, a laser cut to 4 m and 5.6 m, and their slow-scanner
  // decimations, every true reversal was at most 0.2 of the reach and 27 of the 36 false ones
  // 0.25-0.36 (1 m steps of a 4 m laser), each of which lost twice its length.
  if (driven > sp.reverse_max_reach_share * reach(points)) return std::nullopt;
  const Pose2D forward = ekf_.pose();
  Pose2D backward = before.compose(Pose2D{-u.x, -u.y, u.yaw});
  backward.yaw = forward.yaw;  // the turn (and a gyro's correction of it) stands either way
  const LikelihoodGrid& grid = seedGrid();
  // Cheap test first: the full searches run only where backwards already fits better.
  if (grid.score(transformPoints(points, backward)) <= grid.score(transformPoints(points, forward))) return std::nullopt;
  // Both directions are searched alike (no along-track prior, which would favour neither).
  const SeedPrior prior = seedPrior(before, u).isotropic();
  const double xy = std::min(sp.max_xy, driven), yaw = std::min(sp.max_yaw, sp.window_sigmas * prior.yaw);
  const CorrelativeMatch ahead = seedMatch(points, forward, xy, yaw, prior);
  const CorrelativeMatch behind = seedMatch(points, backward, xy, yaw, prior);
  if (!behind.found || behind.score <= (ahead.found ? ahead.score : 0.0) + sp.reverse_margin) return std::nullopt;
  return backward;
}

ScanStep LocalTracker::track(const LaserScan& scan) {
  ScanStep step;
  step.reason = scanProblem(scan);
  if (!step.reason.empty()) return step;
  if (validBeams(scan) < 20) {
    step.reason = "fewer than 20 valid returns";
    return step;
  }
  step.used = true;
  const size_t given_up_before = searches_given_up_;
  const Pose2D raw = odometry_;
  // Without odometry the scan is predicted to move as the last one did.
  const Pose2D u = odometry_available_ ? calibration_.correct(raw) : last_motion_;
  odometry_ = Pose2D{};
  step.odometry_doubted = odometry_available_ && scans_ > 0 && doubted(u, scan.stamp);
  last_stamp_ = scan.stamp;
  if (scans_ > 0) rememberStride(u);
  const Pose2D before = ekf_.pose();
  const Eigen::Matrix3d before_cov = ekf_.covariance();
  if (scans_ > 0) {
    ekf_.predict(u);
    if (!odometry_available_) ekf_.reset(ekf_.pose(), ekf_.covariance() + noOdometryCovariance());
    if (params_.use_imu && have_gyro_ && gyro_var_ > 0) {
      // Against the raw odometry: its calibration learns from matches the gyro has steered.
      if (odometry_available_ && gyro_check_.observe(raw.yaw, gyro_yaw_)) step.gyro_problem = gyro_check_.problem();
      if (gyro_check_.refused()) step.gyro_set_aside = true;
      else step.imu_used = ekf_.updateYawIncrement(gyro_yaw_, gyro_var_);
    }
  }
  // What the gyro says the robot turned, for the no-motion hypothesis of a doubted increment.
  const double turned = step.imu_used ? gyro_yaw_ : 0.0;
  gyro_yaw_ = gyro_var_ = 0;
  have_gyro_ = false;

  if (params_.use_scan_matching && !matcher_.empty()) {
    const SeedParams& sp = params_.seed;
    // The scan as the correlative searches see it (thinned to their grid), made once per scan.
    const Points2 points = sp.enabled ? thinPoints(scanPoints(scan, laser_in_base_), sp.resolution) : Points2{};
    // Too few returns to tell a wrong fit from the right one: the odometry stands, whatever fits.
    const bool can_overrule = points.size() >= static_cast<size_t>(std::max(0, sp.overrule_min_points));
    step.few_returns = sp.enabled && !can_overrule;
    if (scans_ > 0 && odometry_available_ && !step.odometry_doubted && can_overrule) {
      // Some odometry reports speed without its sign (every backward step of the bundled
      // CARMEN logs is written as forward motion): the scan decides the direction.
      if (const auto backward = reversedPrediction(points, before, u)) {
        step.odometry_reversed = true;
        ekf_.reset(*backward, ekf_.covariance());
      }
    }
    Pose2D guess = ekf_.pose();
    const Eigen::Matrix3d& P = ekf_.covariance();
    const double sigma_xy = std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(P.topLeftCorner<2, 2>()).eigenvalues().maxCoeff());
    const double sigma_yaw = std::sqrt(P(2, 2));
    // Odometry that says the robot stood still while the scan hardly fits the local map where
    // it stood has missed a motion (Seattle: 0 where the scan turned 80 degrees on the spot):
    // the scan is searched for at every heading. A robot that drove may have reached new
    // ground, where a low fit says nothing (slow scanners: every 3rd to 5th scan broke), and one
    // whose odometry turned past the seed's own window has not missed its motion.
    const bool stood = odometry_available_ && scans_ > 0 && !step.imu_used &&
                       std::hypot(u.x, u.y) < kStoodStill && std::abs(u.yaw) < sp.max_yaw;
    const bool uncertain = step.odometry_doubted || sigma_xy > sp.min_sigma_xy || sigma_yaw > sp.min_sigma_yaw;
    const bool check_lost = stood && sp.lost_below_score > 0 && can_overrule;
    const double fit = sp.enabled && (uncertain || check_lost) ? seedGrid().score(transformPoints(points, guess)) : 0.0;
    const bool lost = sp.enabled && check_lost && fit < sp.lost_below_score;
    if (sp.enabled && (uncertain || lost)) {
      const double max_xy = odometry_available_ ? sp.max_xy : params_.no_odometry_max_xy;
      const double max_yaw = odometry_available_ ? sp.max_yaw : params_.no_odometry_max_yaw;
      const double xy = step.odometry_doubted || lost ? max_xy : std::min(max_xy, sp.window_sigmas * sigma_xy);
      // Wheels slip while turning more than the motion model says; a gyro does not. Without
      // one, where the scan fits the local map poorly at the prediction (as it does after a
      // turn the odometry missed), the window is never narrower than min_yaw.
      step.prediction = guess;
      step.prediction_score = fit;
      const double min_yaw = step.imu_used || step.prediction_score >= sp.min_yaw_below_score ? 0.0 : sp.min_yaw;
      const double yaw = lost ? M_PI
                         : step.odometry_doubted ? max_yaw
                                                 : std::max(min_yaw, std::min(max_yaw, sp.window_sigmas * sigma_yaw));
      // A reversed increment is the scan's guess, not odometry's measurement: its length earns
      // no tighter prior.
      const SeedPrior prior = !odometry_available_ ? noOdometryPrior()
                              : step.odometry_reversed ? seedPrior(before, u).isotropic()
                                                       : seedPrior(before, u);
      CorrelativeMatch seed = seedMatch(points, guess, xy, yaw, prior);
      // Nothing near the prediction, and the scan hardly fits there: the odometry may have missed
      // a turn while it drove (Seattle, every 3rd scan: a 1 m step the reference turns 103
      // degrees over and the odometry 23; the map came out rotated from there, 6.2 m global error).
      if (!seed.found && !lost && !step.odometry_doubted && odometry_available_ && !step.imu_used && can_overrule &&
          fit < sp.lost_below_score) {
        if (auto turned_more = missedTurn(points, guess, max_xy, prior.isotropic(), fit, step.odometry_turn_doubted)) {
          seed = *turned_more;
          step.odometry_missed_turn = true;
        }
      }
      if (step.odometry_doubted && can_overrule) {
        const Pose2D still{before.x, before.y, Pose2D::normalizeAngle(before.yaw + turned)};
        const CorrelativeMatch at_rest = seedMatch(points, still, xy, yaw, prior.isotropic());  // drove nowhere
        // Odometry is data: the robot stood still only when the scan clearly says so (along a
        // corridor both hypotheses find a pose that fits about as well).
        // A scan that fits poorly at rest too says nothing about where the robot is: a slow
        // scanner's long step into new ground fits nowhere near it (Belgioioso every 5th scan:
        // 4.5 m, fitting 0.01 where odometry put it and 0.12 at rest, was dropped as a jump).
        if (at_rest.found && at_rest.score >= sp.jump_min_score && (!seed.found || at_rest.score > seed.score + sp.jump_margin)) {
          // The scan agrees better with no motion: the increment was a jump, not motion.
          step.odometry_jump = true;
          seed = at_rest;
          ekf_.reset(still, before_cov + Eigen::Matrix3d::Identity() * 0.01);
        }
      }
      if (seed.found) {
        guess = seed.pose;
        step.seeded = true;
        step.seed = seed.pose;
        step.seed_score = seed.score;
      }
    }
    step.match = matcher_.match(scan, guess, step.seeded ? sp.icp_correspondence : 0.0);
    if (!step.match.ok && step.seeded && seedConfirms(step)) {
      // Scans far apart overlap little, so ICP pairs few points; when it lands where the
      // correlative search put the scan, two methods agree and the match stands.
      step.match.ok = true;
      step.match.reason.clear();
    }
    if (!step.match.ok && step.seeded && can_overrule && seedStandsAlone(step)) {
      // ICP pairs too few points to confirm (scans metres apart share little), yet the scan
      // fits the local map far better at the seed than where odometry put it: odometry erred
      // beyond what ICP can pull back, so the seed is the measurement, at the search's
      // resolution. Taking the prediction instead would keep odometry's error for sure.
      step.match.pose = step.seed;
      step.match.covariance = Eigen::Vector3d(sp.alone_sigma_xy * sp.alone_sigma_xy, sp.alone_sigma_xy * sp.alone_sigma_xy,
                                              sp.alone_sigma_yaw * sp.alone_sigma_yaw).asDiagonal();
      step.match.ok = true;
      step.match.reason.clear();
      step.seed_alone = true;
    }
    if (step.match.ok) {
      // A doubted prediction is worthless as a prior: let the match decide.
      if (step.odometry_doubted) ekf_.reset(ekf_.pose(), ekf_.covariance() + Eigen::Matrix3d::Identity());
      step.matched = ekf_.updatePose(step.match.pose, step.match.covariance);
      if (!step.matched && can_overrule && scanPrefers(points, step.match.pose, ekf_.pose())) {
        // The gate says the match is far from the prediction, but the scan fits the local map
        // clearly better there: the odometry slipped (a bump, a wheel off the floor) while
        // predicting with confidence. Trust the scan.
        step.odometry_slipped = true;
        ekf_.reset(ekf_.pose(), ekf_.covariance() + Eigen::Matrix3d::Identity());
        step.matched = ekf_.updatePose(step.match.pose, step.match.covariance);
      }
      step.gated = !step.matched;
    }
  }
  if (scans_ > 0 && odometry_available_ && step.matched && !step.odometry_jump && !step.odometry_slipped &&
      !step.odometry_reversed &&
      (step.match.goodness >= params_.graph.weak_match_goodness ||
       (params_.odometry_calibration.from_seeds && step.seeded && seedConfirms(step))))
    calibration_.learn(raw, before.inverse().compose(ekf_.pose()));
  matcher_.addIfKey(scan, ekf_.pose());
  last_motion_ = scans_ > 0 ? before.inverse().compose(ekf_.pose()) : Pose2D{};
  step.searches_given_up = static_cast<int>(searches_given_up_ - given_up_before);
  ++scans_;
  return step;
}

}  // namespace mrslam::slam
