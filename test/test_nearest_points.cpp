// ICP's pairing: the bucket grid against a brute-force search, and the grid-indexed map's
// pairs against MRPT's own (k-d tree) pairs on real Intel scans, to the bit.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/poses/CPose2D.h>

#include "mrslam/slam/grid_indexed_points_map.h"
#include "mrslam/slam/laser_scan.h"
#include "mrslam/slam/nearest_point_grid.h"
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

// The reference of a tracker: the returns of 40 consecutive Intel scans at their reference
// poses, in the map frame.
GridIndexedPointsMap intelReference(mrpt::maps::CSimplePointsMap& plain, int first, int count) {
  GridIndexedPointsMap indexed;
  const auto& log = test::intelLog();
  for (int i = first; i < first + count; ++i) {
    const auto& record = log.records.at(i);
    for (const auto& [x, y] : scanPoints(record.scan, record.reference.compose(log.laser_in_base))) {
      indexed.insertPointFast(x, y, 0);
      plain.insertPointFast(x, y, 0);
    }
  }
  indexed.mark_as_modified();
  plain.mark_as_modified();
  indexed.index();
  return indexed;
}

TEST(GridIndexedPointsMap, PairsAreMrptsOwnOnRealIntelScans) {
  const auto& log = test::intelLog();
  std::mt19937 rng(11);
  std::normal_distribution<double> xy(0, 0.05), yaw(0, 0.02);  // an ICP start or midway
  int compared = 0;
  for (const int first : {100, 400, 800}) {
    mrpt::maps::CSimplePointsMap plain;
    const GridIndexedPointsMap indexed = intelReference(plain, first, 40);
    for (int i = first + 40; i < first + 60; ++i) {
      const auto& record = log.records.at(i);
      mrpt::maps::CSimplePointsMap scan;  // in the robot's frame, as ICP moves it
      for (const auto& [x, y] : scanPoints(record.scan, log.laser_in_base)) scan.insertPointFast(x, y, 0);
      const Pose2D& truth = record.reference;
      const mrpt::poses::CPose2D pose(truth.x + xy(rng), truth.y + xy(rng), truth.yaw + yaw(rng));
      for (const float max_dist : {0.5f, 0.125f, 0.03f}) {
        for (const float angular : {0.0f, 0.05f}) {
          mrpt::maps::TMatchingParams params;
          params.maxDistForCorrespondence = max_dist;
          params.maxAngularDistForCorrespondence = angular;
          params.angularDistPivotPoint = mrpt::math::TPoint3D(pose.x(), pose.y(), 0);
          params.decimation_other_map_points = 2;
          params.offset_other_map_points = i % 2;
          mrpt::tfest::TMatchingPairList mrpt_pairs, our_pairs;
          mrpt::maps::TMatchingExtraResults mrpt_extra, our_extra;
          plain.determineMatching2D(&scan, pose, mrpt_pairs, params, mrpt_extra);
          indexed.determineMatching2D(&scan, pose, our_pairs, params, our_extra);
          ASSERT_EQ(our_pairs.size(), mrpt_pairs.size()) << "scan " << i << " within " << max_dist;
          for (size_t k = 0; k < our_pairs.size(); ++k) {
            EXPECT_EQ(our_pairs[k].localIdx, mrpt_pairs[k].localIdx);
            EXPECT_EQ(our_pairs[k].errorSquareAfterTransformation, mrpt_pairs[k].errorSquareAfterTransformation);
            // Equally near reference points may be told apart differently; none was here.
            EXPECT_EQ(our_pairs[k].globalIdx, mrpt_pairs[k].globalIdx);
          }
          EXPECT_EQ(our_extra.correspondencesRatio, mrpt_extra.correspondencesRatio);
          EXPECT_EQ(our_extra.sumSqrDist, mrpt_extra.sumSqrDist);
          compared += static_cast<int>(our_pairs.size());
        }
      }
    }
  }
  EXPECT_GT(compared, 10000) << "the comparison must see many pairs";
}

TEST(GridIndexedPointsMap, NoPairsWhenTheBoxesMissEachOtherAsInMrpt) {
  // Two points 0.1 m apart across the boxes' edge: within reach, yet MRPT pairs nothing.
  GridIndexedPointsMap indexed;
  mrpt::maps::CSimplePointsMap plain, other;
  for (auto* map : {static_cast<mrpt::maps::CSimplePointsMap*>(&indexed), &plain}) {
    map->insertPointFast(0, 0, 0);
    map->insertPointFast(1, 0, 0);
  }
  indexed.index();
  other.insertPointFast(1.1f, 0, 0);
  other.insertPointFast(2.0f, 0, 0);
  mrpt::maps::TMatchingParams params;
  params.maxDistForCorrespondence = 0.5f;
  mrpt::tfest::TMatchingPairList ours, theirs;
  mrpt::maps::TMatchingExtraResults our_extra, their_extra;
  plain.determineMatching2D(&other, mrpt::poses::CPose2D(), theirs, params, their_extra);
  indexed.determineMatching2D(&other, mrpt::poses::CPose2D(), ours, params, our_extra);
  EXPECT_TRUE(theirs.empty());
  EXPECT_TRUE(ours.empty());
  // Moved 0.2 m back, the boxes overlap and the first point pairs with (1, 0).
  plain.determineMatching2D(&other, mrpt::poses::CPose2D(-0.2, 0, 0), theirs, params, their_extra);
  indexed.determineMatching2D(&other, mrpt::poses::CPose2D(-0.2, 0, 0), ours, params, our_extra);
  ASSERT_EQ(ours.size(), 1u);
  ASSERT_EQ(theirs.size(), 1u);
  EXPECT_EQ(ours[0].globalIdx, 1u);
  EXPECT_EQ(our_extra.correspondencesRatio, their_extra.correspondencesRatio);
}

TEST(GridIndexedPointsMap, RefusesAnIndexThePointsHaveOutgrown) {
  mrpt::maps::CSimplePointsMap plain;
  GridIndexedPointsMap indexed = intelReference(plain, 100, 2);
  indexed.insertPointFast(0, 0, 0);
  mrpt::tfest::TMatchingPairList pairs;
  mrpt::maps::TMatchingExtraResults extra;
  EXPECT_THROW(indexed.determineMatching2D(&plain, mrpt::poses::CPose2D(), pairs, {}, extra), std::logic_error);
  indexed.index();
  EXPECT_NO_THROW(indexed.determineMatching2D(&plain, mrpt::poses::CPose2D(), pairs, {}, extra));
  EXPECT_GT(pairs.size(), 100u);
}

}  // namespace
}  // namespace mrslam::slam
