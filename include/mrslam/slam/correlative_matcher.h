// Correlative scan matching over a window of poses (Olson 2009, "Real-time correlative scan
// matching"), searched exhaustively but fast by branch and bound over max-pooled copies of
// the likelihood grid (the scheme of Cartographer's fast correlative scan matcher): the
// pose in the window under which the scan's points score highest on the grid, found exactly
// at the grid's resolution and an angular step that moves the farthest point by one cell.
//
// Used where ICP alone has too small a basin: to seed the local tracker when odometry is poor
// or scans are far apart, and to find loop closures against older parts of the map.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "mrslam/grid.h"
#include "mrslam/slam/likelihood_grid.h"

namespace mrslam::slam {

struct SearchWindow {
  Pose2D center;      // the scan frame's pose in the grid's frame at the window's centre
  double xy = 0.5;    // m either way in x and y
  double yaw = 0.35;  // rad either way
  // Optional prior around the centre (as Karto weighs its correlative response): a pose's
  // score is multiplied by max(min_penalty, 1 - gain * (d / sigma_xy)^2) and by the same in
  // yaw, so that where the scan alone cannot tell (along a corridor) the centre wins. Off
  // while sigma_xy (sigma_yaw) is 0.
  double sigma_xy = 0, sigma_yaw = 0;
  double penalty_gain = 0.05, min_penalty = 0.5;
  // Optional, with sigma_xy: offsets along `along_direction` (rad, in the grid's frame) get a
  // factor of their own, max(min_penalty_along, 1 - gain * (d / sigma_along)^2), and sigma_xy
  // then weighs offsets across that direction only (odometry knows how far it drove better than
  // where it went). Off while sigma_along is 0.
  double sigma_along = 0, along_direction = 0, min_penalty_along = 0.5;
};

struct CorrelativeMatch {
  bool found = false;  // a pose scoring at least min_score exists in the window
  Pose2D pose;         // best pose (scan frame in the grid's frame)
  double score = 0;    // mean likelihood of the scan's points at that pose, 0..1, times the prior
  bool exhausted = false;  // gave up after kMaxEvaluations candidates: found is false
};

// The branch and bound prunes little where the grid scores alike everywhere (a map smeared by a
// lost track, a lone node's 8 m / 46 degree window on it): ACES without odometry, whose track is
// lost, ran for more than ten minutes on such searches. None of the 171 542 searches of the
// bundled logs and their decimations (every 3rd to 7th scan, every phase, scans dropped at
// random) scored more than 466 353 candidates; past this many a search gives up, which costs a
// second or less.
constexpr size_t kMaxEvaluations = 500000;

class CorrelativeMatcher {
 public:
  // Precomputes `levels` max-pooled copies of the grid (level h pools 2^h x 2^h cells).
  CorrelativeMatcher(std::shared_ptr<const LikelihoodGrid> grid, int levels = 6);
  // Not copyable: the levels point into the grid and into their own buffers.
  CorrelativeMatcher(const CorrelativeMatcher&) = delete;
  CorrelativeMatcher& operator=(const CorrelativeMatcher&) = delete;
  // Builds the levels again after the grid was rebuilt in place (LikelihoodGrid::rebuild), in
  // their own buffers.
  void refresh();

  // A pose at least this far from a match (or turned this much from it) is a distinct rival of
  // it, not the same peak: what the loop closer and the tracker's missed-turn search weigh a
  // match against.
  static constexpr double kRivalMinXy = 1.0;     // m
  static constexpr double kRivalMinYaw = 0.087;  // rad (5 degrees)

  // The best pose in the window for `points` (in the scan frame); not found when no pose
  // scores min_score. With `excluded`, poses within `exclude_xy` m and `exclude_yaw` rad of it
  // are not candidates: the best rival elsewhere in the window (how ambiguous the match is).
  CorrelativeMatch match(const Points2& points, const SearchWindow& window, double min_score,
                         const Pose2D* excluded = nullptr, double exclude_xy = 0, double exclude_yaw = 0) const;

  const LikelihoodGrid& grid() const { return *grid_; }
  // Bytes held by the grid and its max-pooled copies (what a cache of matchers must budget).
  size_t bytes() const;
  // The bytes a matcher of `levels` levels on `grid` will hold, known before it is built (a
  // cache makes room first rather than holding the new one beside a full budget).
  static size_t bytesFor(const LikelihoodGrid& grid, int levels);

 private:
  struct Level {
    int offset = 0;  // cell (0, 0) of this level is cell (-offset, -offset) of the grid
    int width = 0, height = 0;
    std::vector<uint8_t> pooled;     // levels above 0; level 0 reads the grid's own cells...
    const uint8_t* values = nullptr;  // ...through this (no copy of the largest array)
  };
  struct Candidate;
  struct Rotated;
  // Sum of the level's cells under `cells` shifted by (dx, dy); cells outside count 0.
  // `linear` is the rotated cells' row-major index on this level (rowIndex), for the candidates
  // wholly inside it.
  static int64_t sumAt(const Level& level, const Rotated& rotated, const int32_t* linear, int dx, int dy);
  // The cells' index cy * width + cx on `level`, written to `out` (an index per cell).
  static void rowIndex(const Level& level, const Rotated& rotated, int32_t* out);
  // Levels 0.. from the grid, in the levels' own buffers; `row_pass` is scratch.
  void buildLevels(std::vector<uint8_t>& row_pass);

  std::shared_ptr<const LikelihoodGrid> grid_;
  std::vector<Level> levels_;
  std::vector<uint8_t> row_pass_;  // refresh()'s scratch (a level maxed along its rows), kept for the next
};

}  // namespace mrslam::slam
