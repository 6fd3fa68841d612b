// The benchmark's split of a global error into what the headings and what the positions make
// (bench/trajectory_metrics.h), on the Intel log's reference path.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mrslam/bench/trajectory_metrics.h"
#include "test_logs.h"

namespace {

using mrslam::Pose2D;
namespace bench = mrslam::bench;

// The reference path in a frame of its own (as a SLAM run would give it), with each heading
// and position disturbed by the given standard deviations (seeded).
std::vector<Pose2D> disturbed(const std::vector<Pose2D>& reference, double sigma_yaw, double sigma_xy) {
  const Pose2D frame{12.0, -7.0, 2.0};
  std::mt19937 rng(7);
  std::normal_distribution<double> yaw(0.0, sigma_yaw), xy(0.0, sigma_xy);
  std::vector<Pose2D> out;
  for (const Pose2D& p : reference) {
    const Pose2D moved{p.x + xy(rng), p.y + xy(rng), p.yaw + yaw(rng)};
    out.push_back(frame.compose(moved));
  }
  return out;
}

TEST(GlobalErrorSplit, HeadingsAndPositionsEachKeepTheirOwnShare) {
  std::vector<Pose2D> reference;
  for (const auto& r : mrslam::test::intelLog().records) reference.push_back(r.reference);
  const auto pairs = bench::randomPairs(reference.size(), 500, 2009);

  // Headings off by 1 degree (sigma), positions exact: all of the error is the headings'.
  const auto headings = bench::splitGlobalError(disturbed(reference, M_PI / 180, 0.0), reference, pairs);
  EXPECT_LT(headings.own_positions, 1e-6);
  EXPECT_GT(headings.own_headings, 0.1);  // Intel's relations span metres: ~1.7 cm per metre
  EXPECT_NEAR(headings.own_headings,
              bench::relationError(disturbed(reference, M_PI / 180, 0.0), reference, pairs).trans_mean, 1e-9);

  // Positions off by 5 cm, headings exact: the headings make next to none of it (the frame
  // fitted to noisy positions turns every heading by a hair).
  const auto positions = bench::splitGlobalError(disturbed(reference, 0.0, 0.05), reference, pairs);
  EXPECT_LT(positions.own_headings, 0.01);
  // A relation's error is then the difference of two independent 2D errors of 5 cm per axis:
  // Rayleigh with 5 cm x sqrt(2) per axis, whose mean is that times sqrt(pi / 2).
  EXPECT_NEAR(positions.own_positions, 0.05 * std::sqrt(2.0) * std::sqrt(M_PI / 2), 0.015);
}

}  // namespace
