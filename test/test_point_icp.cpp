// ICP: the bucket grid that finds its pairs against a brute-force search, and our ICP against
// MRPT's CICP (which the tracker used before, point_icp.h says why no longer) on real Intel scans.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/slam/CICP.h>

#include "mrslam/slam/laser_scan.h"
#include "mrslam/slam/nearest_point_grid.h"
#include "mrslam/slam/point_icp.h"
#include "test_logs.h"

namespace mrslam::slam {
namespace {

struct Cloud {
  std::vector<float> x, y;
};

// Points along random wall segments (as scans give them), a few loose ones, and some that
// must never be found (NaN, infinite).
Cloud wallsCloud(std::mt19937& rng) {
  std::uniform_real_distribution<float> coord(-20, 20), unit(0, 1), noise(-0.01f, 0.01f);
  Cloud cloud;
  for (int wall = 0; wall < 30; ++wall) {
    const float x0 = coord(rng), y0 = coord(rng), x1 = x0 + coord(rng) / 4, y1 = y0 + coord(rng) / 4;
    for (int k = 0; k < 200; ++k) {
      const float t = unit(rng);
      cloud.x.push_back(x0 + t * (x1 - x0) + noise(rng));
      cloud.y.push_back(y0 + t * (y1 - y0) + noise(rng));
    }
  }
  for (int k = 0; k < 50; ++k) {
    cloud.x.push_back(coord(rng));
    cloud.y.push_back(coord(rng));
  }
  cloud.x.push_back(std::numeric_limits<float>::quiet_NaN());
  cloud.y.push_back(0);
  cloud.x.push_back(0);
  cloud.y.push_back(std::numeric_limits<float>::infinity());
  return cloud;
}

float bruteForceNearest(const Cloud& cloud, float x, float y, float max_dist) {
  float best = max_dist * max_dist;
  for (size_t i = 0; i < cloud.x.size(); ++i) {
    if (!std::isfinite(cloud.x[i]) || !std::isfinite(cloud.y[i])) continue;
    const float dx = cloud.x[i] - x, dy = cloud.y[i] - y;
    best = std::min(best, dx * dx + dy * dy);
  }
  return best;
}

TEST(NearestPointGrid, FindsWhatABruteForceSearchFindsInsideAndOutsideTheGrid) {
  std::mt19937 rng(7);
  const Cloud cloud = wallsCloud(rng);
  std::uniform_real_distribution<float> query(-30, 30), offset(-0.05f, 0.05f);
  std::uniform_int_distribution<size_t> point(0, cloud.x.size() - 3);  // a finite one
  // Default cells, and a cell budget so small that the cells must grow (and hold many points).
  for (const size_t max_cells : {size_t{1} << 21, size_t{64}}) {
    NearestPointGrid grid;
    grid.build(cloud.x.data(), cloud.y.data(), cloud.x.size(), 0.1f, max_cells);
    EXPECT_EQ(grid.size(), cloud.x.size() - 2) << "the two non-finite points are left out";
    if (max_cells < 1000) {
      EXPECT_GT(grid.cellSize(), 1.0f) << "40 m of points in 64 cells: the cells grew";
    }
    int found = 0;
    for (int q = 0; q < 4000; ++q) {
      // Half anywhere (in and around the grid), half next to a wall, where ICP asks.
      const size_t near = point(rng);
      const float x = q % 2 ? query(rng) : cloud.x[near] + offset(rng);
      const float y = q % 2 ? query(rng) : cloud.y[near] + offset(rng);
      for (const float max_dist : {0.02f, 0.3f, 2.5f, 60.0f}) {
        const float expected = bruteForceNearest(cloud, x, y, max_dist);
        const auto got = grid.nearest(x, y, max_dist);
        if (expected >= max_dist * max_dist) {
          EXPECT_EQ(got.index, -1) << x << "," << y << " within " << max_dist;
          continue;
        }
        ASSERT_GE(got.index, 0) << x << "," << y << " within " << max_dist;
        EXPECT_EQ(got.dist_sq, expected) << x << "," << y << " within " << max_dist;
        const float dx = cloud.x[got.index] - x, dy = cloud.y[got.index] - y;
        EXPECT_EQ(dx * dx + dy * dy, got.dist_sq) << "the index is the point at that distance";
        ++found;
      }
    }
    EXPECT_GT(found, 8000) << "most queries should find a point";
  }
}

TEST(NearestPointGrid, EmptyOrUnreachableQueriesFindNothing) {
  NearestPointGrid grid;
  grid.build(nullptr, nullptr, 0, 0.1f);
  EXPECT_EQ(grid.nearest(0, 0, 100).index, -1);
  const float x[] = {1.0f}, y[] = {1.0f};
  grid.build(x, y, 1, 0.1f);
  EXPECT_EQ(grid.nearest(1.05f, 1.0f, 0.1f).index, 0);
  EXPECT_EQ(grid.nearest(1e30f, 0, 1).index, -1) << "far outside (beyond int) the grid";
  EXPECT_EQ(grid.nearest(1e30f, 0, 1e30f).index, -1) << "beyond int, however far it may reach";
  EXPECT_EQ(grid.nearest(-5e5f, 0, std::numeric_limits<float>::infinity()).index, 0);
  EXPECT_EQ(grid.nearest(std::nanf(""), 0, 1).index, -1);
  EXPECT_EQ(grid.nearest(1, 1, std::nanf("")).index, -1);
  EXPECT_EQ(grid.nearest(1, 1, -1).index, -1);
}

using Points = std::vector<std::pair<float, float>>;

// The reference of a tracker: the returns of `count` consecutive Intel scans at their reference
// poses, in the map frame.
Points intelReference(int first, int count) {
  const auto& log = test::intelLog();
  Points points;
  for (int i = first; i < first + count; ++i) {
    const auto& record = log.records.at(i);
    const auto returns = scanPoints(record.scan, record.reference.compose(log.laser_in_base));
    points.insert(points.end(), returns.begin(), returns.end());
  }
  return points;
}

mrpt::maps::CSimplePointsMap mrptPoints(const Points& points) {
  mrpt::maps::CSimplePointsMap map;
  for (const auto& [x, y] : points) map.insertPointFast(x, y, 0);
  map.mark_as_modified();
  return map;
}

// MRPT's CICP with the schedule the tracker gave it.
IcpResult mrptIcp(const Points& reference, const Points& points, const Pose2D& guess, const IcpSchedule& schedule) {
  mrpt::slam::CICP icp;
  icp.options.maxIterations = static_cast<unsigned>(schedule.max_iterations);
  icp.options.thresholdDist = schedule.max_correspondence;
  icp.options.thresholdAng = 0;
  icp.options.smallestThresholdDist = schedule.min_correspondence;
  icp.options.ALFA = 0.5;
  icp.options.corresponding_points_decimation = static_cast<uint32_t>(schedule.decimation);
  icp.options.onlyUniqueRobust = false;
  const auto ref_map = mrptPoints(reference), scan_map = mrptPoints(points);
  mrpt::slam::CICP::TReturnInfo info;
  const auto pdf = icp.Align(&ref_map, &scan_map, mrpt::poses::CPose2D(guess.x, guess.y, guess.yaw), info);
  mrpt::poses::CPosePDFGaussian gaussian;
  gaussian.copyFrom(*pdf);
  IcpResult result;
  result.pose = {gaussian.mean.x(), gaussian.mean.y(), gaussian.mean.phi()};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) result.covariance(r, c) = gaussian.cov(r, c);
  result.goodness = info.goodness;
  result.iterations = static_cast<int>(info.nIterations);
  return result;
}

TEST(PointIcp, AlignsRealIntelScansAsMrptsIcpDid) {
  const auto& log = test::intelLog();
  std::mt19937 rng(11);
  int accepted = 0, alike = 0, compared = 0;
  double our_error = 0, their_error = 0;  // summed over the accepted matches, m
  double farthest_apart = 0;              // m
  constexpr double kMinGoodness = 0.3;  // the tracker's min_goodness
  for (int i = 60; i < 900; i += 14) {
    // The tracker's case: scan i against the returns of the 40 scans before it.
    const Points reference = intelReference(i - 40, 40);
    PointIcp ours;
    ours.setReference(reference);
    const auto& record = log.records.at(i);
    const Points scan = scanPoints(record.scan, log.laser_in_base);  // in the robot's frame
    const Pose2D& truth = record.reference;
    // A tracker's guess, and one as far off as a poor odometry step.
    for (const double spread : {0.05, 0.2}) {
      std::normal_distribution<double> xy(0, spread), yaw(0, spread / 2);
      const Pose2D guess{truth.x + xy(rng), truth.y + xy(rng), truth.yaw + yaw(rng)};
      IcpSchedule schedule;
      schedule.decimation = 1 + i % 2;
      const IcpResult mine = ours.align(scan, guess, schedule);
      const IcpResult theirs = mrptIcp(reference, scan, guess, schedule);
      ++compared;
      // A match MRPT's ICP would have refused is refused here too.
      if (theirs.goodness < kMinGoodness) {
        EXPECT_LT(mine.goodness, kMinGoodness) << "scan " << i;
        continue;
      }
      ++accepted;
      ASSERT_TRUE(mine.paired);
      // Both end within a fifth of a cell (1 cm, 0.3 degrees) of each other...
      EXPECT_NEAR(mine.pose.x, theirs.pose.x, 0.01) << "scan " << i;
      EXPECT_NEAR(mine.pose.y, theirs.pose.y, 0.01) << "scan " << i;
      EXPECT_NEAR(Pose2D::normalizeAngle(mine.pose.yaw - theirs.pose.yaw), 0, 0.005) << "scan " << i;
      our_error += std::hypot(mine.pose.x - truth.x, mine.pose.y - truth.y);
      their_error += std::hypot(theirs.pose.x - truth.x, theirs.pose.y - truth.y);
      // ...and almost always at the same pose with the same pairs: MRPT sums in float, we in
      // double, and a rounding apart can tip a pair in or out at the last pairing distance, or
      // stop a run that is out of iterations (the distance then shrinks by force) elsewhere.
      bool same = std::abs(mine.pose.x - theirs.pose.x) < 1e-4 && std::abs(mine.pose.y - theirs.pose.y) < 1e-4 &&
                  std::abs(Pose2D::normalizeAngle(mine.pose.yaw - theirs.pose.yaw)) < 1e-5 &&
                  std::abs(mine.goodness - theirs.goodness) < 1e-6;
      for (int k = 0; k < 3; ++k) {
        same = same && std::abs(mine.covariance(k, k) - theirs.covariance(k, k)) < 0.01 * theirs.covariance(k, k);
      }
      alike += same;
      farthest_apart = std::max(farthest_apart, std::hypot(mine.pose.x - theirs.pose.x, mine.pose.y - theirs.pose.y));
    }
  }
  EXPECT_EQ(compared, 120);
  EXPECT_GT(accepted, 100) << "most of the tracker's matches hold";
  EXPECT_GE(alike, accepted * 9 / 10);
  EXPECT_LT(our_error, their_error * 1.05 + 0.005) << "no further from the truth than MRPT's";
  std::printf("PointIcp vs MRPT's CICP: %d compared, %d accepted, %d alike (farthest apart %.4f m); mean error %.4f vs %.4f m\n",
              compared, accepted, alike, farthest_apart, our_error / accepted, their_error / accepted);
}

TEST(NearestPointGrid, ASkippedRangeIsNeverTheAnswer) {
  std::mt19937 rng(11);
  const Cloud cloud = wallsCloud(rng);
  NearestPointGrid grid;
  grid.build(cloud.x.data(), cloud.y.data(), cloud.x.size(), 0.1f);
  const size_t first = 1000, last = 3000;  // walls 5 to 14 of the 30
  std::uniform_int_distribution<size_t> point(0, cloud.x.size() - 3);
  int inside = 0;
  for (int q = 0; q < 2000; ++q) {
    const size_t near = point(rng);
    const float x = cloud.x[near] + 0.01f, y = cloud.y[near];
    // What a brute force search finds outside the range.
    float expected = 0.5f * 0.5f;
    for (size_t i = 0; i < cloud.x.size(); ++i) {
      if ((i >= first && i < last) || !std::isfinite(cloud.x[i]) || !std::isfinite(cloud.y[i])) continue;
      const float dx = cloud.x[i] - x, dy = cloud.y[i] - y;
      expected = std::min(expected, dx * dx + dy * dy);
    }
    const auto got = grid.nearestExcept(x, y, 0.5f, first, last);
    inside += near >= first && near < last;
    if (expected >= 0.25f) {
      EXPECT_EQ(got.index, -1);
      continue;
    }
    ASSERT_GE(got.index, 0);
    EXPECT_TRUE(got.index < static_cast<int64_t>(first) || got.index >= static_cast<int64_t>(last)) << got.index;
    EXPECT_EQ(got.dist_sq, expected);
  }
  EXPECT_GT(inside, 300) << "many queries lie on the range's own walls";
  // An empty range, or one beyond every index, leaves the plain answer.
  EXPECT_EQ(grid.nearestExcept(cloud.x[5], cloud.y[5], 0.5f, 7, 7).index, grid.nearest(cloud.x[5], cloud.y[5], 0.5f).index);
  EXPECT_EQ(grid.nearestExcept(cloud.x[5], cloud.y[5], 0.5f, size_t{1} << 40, size_t{1} << 41).index, 5);
}

// A reference holding the scan itself pins the scan where it is; leaving its own points out
// (as the final refinement does, pose_refinement.h) aligns it to the rest.
TEST(PointIcp, ASkippedRangeOfTheReferenceIsNeverPaired) {
  const Points scan = intelReference(100, 1);
  Points reference = scan;  // the scan itself, where it is...
  for (const auto& [x, y] : scan) reference.emplace_back(x + 0.04f, y);  // ...and a copy 4 cm along x
  PointIcp icp;
  icp.setReference(reference);
  IcpSchedule schedule;
  schedule.max_correspondence = 0.2;
  const IcpResult pinned = icp.align(scan, Pose2D{}, schedule);
  EXPECT_NEAR(pinned.pose.x, 0, 1e-4);
  const IcpResult skipped = icp.align(scan, Pose2D{}, schedule, SkipRange{0, scan.size()});
  ASSERT_TRUE(skipped.paired);
  EXPECT_NEAR(skipped.pose.x, 0.04, 1e-3);
  EXPECT_NEAR(skipped.pose.y, 0, 1e-3);
  EXPECT_GT(skipped.goodness, 0.9);
  // Indices are those given to setReference(), non-finite points included.
  Points with_nan{{std::nanf(""), 0}};
  with_nan.insert(with_nan.end(), reference.begin(), reference.end());
  icp.setReference(with_nan);
  EXPECT_NEAR(icp.align(scan, Pose2D{}, schedule, SkipRange{0, scan.size() + 1}).pose.x, 0.04, 1e-3);
}

TEST(PointIcp, PairsNothingWhenTheBoxesMissEachOther) {
  PointIcp icp;
  icp.setReference({{0, 0}, {1, 0}});
  IcpSchedule schedule;
  // (1.1, 0) lies 0.1 m from (1, 0), but the scan's box misses the reference's: no pairs.
  const IcpResult apart = icp.align({{1.1f, 0}, {2.0f, 0}}, Pose2D{}, schedule);
  EXPECT_FALSE(apart.paired);
  EXPECT_EQ(apart.goodness, 0);
  EXPECT_EQ(apart.pose.x, 0) << "the guess is returned";
}

TEST(PointIcp, EmptyOrNonFiniteInputOrAnEndlessScheduleEnds) {
  PointIcp icp;
  EXPECT_TRUE(icp.empty());
  EXPECT_FALSE(icp.align({{1, 1}}, Pose2D{}, {}).paired);
  icp.setReference({{std::nanf(""), 0}, {0, std::numeric_limits<float>::infinity()}});
  EXPECT_TRUE(icp.empty()) << "non-finite reference points are left out";
  icp.setReference(intelReference(100, 2));
  EXPECT_FALSE(icp.align({}, Pose2D{}, {}).paired);
  EXPECT_FALSE(icp.align({{std::nanf(""), 0}, {0, std::nanf("")}}, Pose2D{}, {}).paired);
  // Schedules that would never end (a distance that never falls below the final one) end.
  const Points scan = intelReference(101, 1);
  IcpSchedule endless;
  endless.max_iterations = 0;
  endless.min_correspondence = -1;
  EXPECT_TRUE(icp.align(scan, Pose2D{}, endless).paired);
  endless.max_correspondence = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(icp.align(scan, Pose2D{}, endless).paired);
}

}  // namespace
}  // namespace mrslam::slam
