// One test group per stage of the fusion pipeline, on crops of real maps.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc.hpp>

#include "mrslam/bench/pair_maker.h"
#include "mrslam/fusion/approximate_pose.h"
#include "mrslam/fusion/chamfer_polish.h"
#include "mrslam/fusion/correlation_search.h"
#include "mrslam/fusion/edge_smoothing.h"
#include "mrslam/fusion/grid_merge.h"
#include "mrslam/fusion/radon.h"
#include "mrslam/fusion/segment.h"
#include "mrslam/fusion/similarity_index.h"
#include "mrslam/fusion/ternary_image.h"
#include "mrslam/fusion/verification.h"
#include "mrslam/map_io.h"
#include "test_data.h"

using namespace mrslam;
using namespace mrslam::fusion;

namespace {

constexpr double kDeg = M_PI / 180.0;

const OccupancyGrid& intel() {
  static const OccupancyGrid g = loadMap(test::referenceMap("intel"));
  return g;
}

// A 300 x 300 crop of the Intel lab (walls, doors and corners).
cv::Mat intelCrop() { return toTernary(bench::cropGrid(intel(), 250, 230, 300, 300)); }

std::vector<cv::Point2f> transformed(const std::vector<cv::Point2f>& pts, const CellTransform& t) {
  std::vector<cv::Point2f> out;
  for (const auto& p : pts) out.emplace_back(t.apply(p));
  return out;
}

}  // namespace

TEST(TernaryImage, ClassifiesCellsAndKeepsGridRowOrder) {
  const cv::Mat t = toTernary(intel());
  ASSERT_EQ(t.rows, intel().height);
  for (int r = 0; r < t.rows; r += 7)
    for (int c = 0; c < t.cols; c += 5) {
      const int v = intel().at(c, r);
      EXPECT_EQ(t.at<uint8_t>(r, c), v < 0 ? kUnknownCell : (v >= 65 ? kOccupiedCell : kFreeCell));
    }
}

TEST(CannyEdges, EdgesLieOnObstacleBoundariesOnly) {
  const cv::Mat t = intelCrop();
  const cv::Mat edges = cannyEdges(t, CannyParams{});
  ASSERT_GT(cv::countNonZero(edges), 500);
  cv::Mat near;
  cv::dilate(t == kOccupiedCell, near, cv::Mat::ones(3, 3, CV_8U));
  EXPECT_EQ(cv::countNonZero(edges & ~near), 0);
}

TEST(DownsampleTernary, OccupiedWinsThenFree) {
  cv::Mat t = (cv::Mat_<uint8_t>(2, 4) << kUnknownCell, kFreeCell, kUnknownCell, kUnknownCell,  //
               kOccupiedCell, kFreeCell, kUnknownCell, kUnknownCell);
  const cv::Mat d = downsampleTernary(t);
  ASSERT_EQ(d.cols, 2);
  EXPECT_EQ(d.at<uint8_t>(0, 0), kOccupiedCell);
  EXPECT_EQ(d.at<uint8_t>(0, 1), kUnknownCell);
}

TEST(DownsampleTernary, EveryBlockOfARealOddSizedCropIsItsMaximum) {
  // 301 x 299 cells: the last row and column form half blocks.
  const cv::Mat t = toTernary(bench::cropGrid(intel(), 250, 230, 299, 301));
  const cv::Mat d = downsampleTernary(t);
  ASSERT_EQ(d.rows, 151);
  ASSERT_EQ(d.cols, 150);
  for (int r = 0; r < d.rows; ++r)
    for (int c = 0; c < d.cols; ++c) {
      uint8_t best = kUnknownCell;
      for (int rr = 2 * r; rr < std::min(t.rows, 2 * r + 2); ++rr)
        for (int cc = 2 * c; cc < std::min(t.cols, 2 * c + 2); ++cc) best = std::max(best, t.at<uint8_t>(rr, cc));
      ASSERT_EQ(d.at<uint8_t>(r, c), best) << r << "," << c;
    }
}

// The fusion's masks are made a row at a time (a 4000 x 4000 map's whole-image masks cost
// 16 MB of fresh pages each); they must be the whole-image operations they replace.
TEST(TernaryImage, WallsNearRowByRowAreTheWallsDilatedByOneCell) {
  const cv::Mat one_wall = (cv::Mat_<uint8_t>(1, 1) << kOccupiedCell);
  for (const cv::Mat& t : {toTernary(intel()), intelCrop(), one_wall, cv::Mat(intelCrop().row(7))}) {
    cv::Mat dilated;
    cv::dilate(t == kOccupiedCell, dilated, cv::Mat::ones(3, 3, CV_8U));
    int next_row = 0;
    forEachRowWithWallsNear(t, [&](int y, const uint8_t* cells, const uint8_t* near) {
      ASSERT_EQ(y, next_row++);
      ASSERT_EQ(cells, t.ptr<uint8_t>(y));
      for (int x = 0; x < t.cols; ++x) ASSERT_EQ(near[x], dilated.at<uint8_t>(y, x) ? 1 : 0) << y << "," << x;
    });
    EXPECT_EQ(next_row, t.rows);
  }
}

TEST(TernaryImage, KeepsEveryStridethFreeCellAndCountsCellsAsAWholeImageMaskDoes) {
  const cv::Mat t = toTernary(intel());
  const int free_cells = cv::countNonZero(t == kFreeCell);
  ASSERT_GT(free_cells, 100000);
  EXPECT_EQ(countCells(t, kFreeCell), free_cells);
  EXPECT_EQ(countCells(t, kOccupiedCell), cv::countNonZero(t == kOccupiedCell));
  std::vector<cv::Point> all;
  cv::findNonZero(t == kFreeCell, all);  // raster order
  for (const size_t stride : {size_t{1}, size_t{7}, size_t{64}, size_t{200}, size_t{1000000}}) {
    const std::vector<cv::Point2f> kept = everyStridethCell(t, kFreeCell, stride);
    ASSERT_EQ(kept.size(), (all.size() + stride - 1) / stride) << "stride " << stride;
    for (size_t k = 0; k < kept.size(); ++k)
      ASSERT_EQ(kept[k], cv::Point2f(all[k * stride].x + 0.5f, all[k * stride].y + 0.5f)) << "stride " << stride;
  }
}

TEST(EdgeSmoothing, ThickWallBecomesItsOneCellMiddleCurve) {
  // A real wall band: the obstacles of the crop dilated to ~5 cells, as a noisy laser makes.
  const cv::Mat t = intelCrop();
  cv::Mat thick;
  cv::dilate(t == kOccupiedCell, thick, cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5}));
  cv::Mat edges;
  cv::Canny(thick, edges, 50, 150);
  const cv::Mat middle = smoothEdges(edges, 3);
  ASSERT_GT(cv::countNonZero(middle), 300);
  // (Nearly) one cell wide: 2x2 blocks fully set are rare leftovers of the thinning.
  int blocks = 0;
  for (int r = 0; r + 1 < middle.rows; ++r)
    for (int c = 0; c + 1 < middle.cols; ++c)
      blocks += middle.at<uint8_t>(r, c) && middle.at<uint8_t>(r + 1, c) && middle.at<uint8_t>(r, c + 1) &&
                middle.at<uint8_t>(r + 1, c + 1);
  EXPECT_LT(blocks, cv::countNonZero(middle) / 100);
  // The middle curve runs near the true wall (the undilated obstacles), much nearer than the
  // Canny edges on either side of the band do.
  cv::Mat distance;
  cv::distanceTransform(~(t == kOccupiedCell), distance, cv::DIST_L2, 3);
  const double middle_distance = cv::mean(distance, middle)[0];
  const double edge_distance = cv::mean(distance, edges)[0];
  // (measured: 1.66 cells against 2.35; wall ends and corners keep the mean above zero)
  EXPECT_GT(edge_distance, 2.0);
  EXPECT_LT(middle_distance, 0.75 * edge_distance);
}

TEST(EdgeSmoothing, OwnThinningMatchesOpenCvs) {
  const cv::Mat t = intelCrop();
  cv::Mat closed;
  cv::morphologyEx(cannyEdges(t, CannyParams{}), closed, cv::MORPH_CLOSE,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5}));
  cv::Mat reference;
  cv::ximgproc::thinning(closed, reference, cv::ximgproc::THINNING_ZHANGSUEN);
  const cv::Mat ours = thinToMiddleCurves(closed);
  ASSERT_GT(cv::countNonZero(reference), 500);
  EXPECT_EQ(cv::countNonZero((ours != 0) != (reference != 0)), 0);
}

TEST(RandomSegment, WalksConnectedPointsAndIsReproducible) {
  const cv::Mat curves = smoothEdges(cannyEdges(intelCrop(), CannyParams{}), 2);
  std::vector<cv::Point> pts;
  cv::findNonZero(curves, pts);
  std::mt19937 rng1(7), rng2(7);
  int found = 0;
  for (int i = 0; i < 50; ++i) {
    const auto s1 = randomSegment(curves, pts, 30, rng1);
    const auto s2 = randomSegment(curves, pts, 30, rng2);
    ASSERT_EQ(s1.has_value(), s2.has_value());
    if (!s1) continue;
    ++found;
    ASSERT_EQ(s1->size(), 30u);
    EXPECT_EQ(*s1, *s2);
    for (size_t k = 1; k < s1->size(); ++k) {
      EXPECT_LE(std::abs((*s1)[k].x - (*s1)[k - 1].x), 1.0f);
      EXPECT_LE(std::abs((*s1)[k].y - (*s1)[k - 1].y), 1.0f);
      EXPECT_TRUE(curves.at<uint8_t>(cv::Point((*s1)[k])));
    }
  }
  EXPECT_GT(found, 10);
}

TEST(SegmentVerification, RejectsStraightAndBrokenSegmentsAcceptsCorners) {
  SegmentParams params;
  Segment straight, corner, broken;
  for (int i = 0; i < 40; ++i) straight.emplace_back(i, 0);
  for (int i = 0; i < 20; ++i) corner.emplace_back(i, 0);
  for (int i = 1; i <= 20; ++i) corner.emplace_back(19, i);
  for (int i = 0; i < 20; ++i) broken.emplace_back(i, 0);
  for (int i = 0; i < 20; ++i) broken.emplace_back(-60 + i, 70);
  std::string why;
  EXPECT_FALSE(verifySegment(computeSignature(straight, params), params, &why));
  EXPECT_NE(why.find("condition 2"), std::string::npos) << why;
  EXPECT_TRUE(verifySegment(computeSignature(corner, params), params, &why)) << why;
  EXPECT_FALSE(verifySegment(computeSignature(broken, params), params, &why));
  EXPECT_NE(why.find("condition"), std::string::npos);
}

TEST(SegmentVerification, SortsRealRandomSegments) {
  // On a real map some random segments pass (corners, door frames) and some are rejected
  // (straight walls): verification must discriminate, not accept or reject everything.
  const cv::Mat curves = smoothEdges(cannyEdges(intelCrop(), CannyParams{}), 2);
  std::vector<cv::Point> pts;
  cv::findNonZero(curves, pts);
  std::mt19937 rng(3);
  SegmentParams params;
  int accepted = 0, rejected = 0;
  for (int i = 0; i < 200; ++i) {
    const auto s = randomSegment(curves, pts, params.points, rng);
    if (!s) continue;
    (verifySegment(computeSignature(*s, params), params) ? accepted : rejected)++;
  }
  EXPECT_GT(accepted, 5);
  EXPECT_GT(rejected, 5);
}

TEST(CrossCorrelation, SameSegmentRotatedMatchesOthersDoNot) {
  const cv::Mat curves = smoothEdges(cannyEdges(intelCrop(), CannyParams{}), 2);
  std::vector<cv::Point> pts;
  cv::findNonZero(curves, pts);
  std::mt19937 rng(11);
  SegmentParams params;
  std::vector<Segment> verified;
  while (verified.size() < 6) {
    auto s = randomSegment(curves, pts, params.points, rng);
    if (s && verifySegment(computeSignature(*s, params), params)) verified.push_back(*s);
  }
  const CellTransform motion{37 * kDeg, {120.0, -40.0}};
  const Segment moved = transformed(verified[0], motion);
  EXPECT_GT(segmentCorrelation(computeSignature(verified[0], params), computeSignature(moved, params)), 0.99);
  int dissimilar = 0;
  for (size_t k = 1; k < verified.size(); ++k)
    dissimilar += segmentCorrelation(computeSignature(verified[0], params), computeSignature(verified[k], params)) < 0.9;
  EXPECT_GE(dissimilar, 3);
}

TEST(ApproximatePose, RecoversRotationAndTranslationOfAMatchedSegment) {
  const cv::Mat curves = smoothEdges(cannyEdges(intelCrop(), CannyParams{}), 2);
  std::vector<cv::Point> pts;
  cv::findNonZero(curves, pts);
  std::mt19937 rng(5);
  std::optional<Segment> s;
  while (!(s = randomSegment(curves, pts, 40, rng))) {}
  const CellTransform truth{-100 * kDeg, {35.0, 260.0}};
  // Map A holds the moved segment, map B the original: A = truth(B).
  const auto candidates = approximatePose(transformed(*s, truth), *s);
  double best = 1e9;
  for (const CellTransform& c : candidates) {
    double err = 0;
    for (const auto& p : *s) err = std::max(err, cv::norm(c.apply(p) - truth.apply(p)));
    best = std::min(best, err);
  }
  EXPECT_LT(best, 0.5);
}

TEST(Radon, SparseTransformPeaksWhereOpenCvsRadonTransformPeaks) {
  const cv::Mat t = intelCrop();
  cv::Mat image = (t == kOccupiedCell);
  cv::Mat radon;
  cv::ximgproc::RadonTransform(image, radon, 1, 0, 180, false, false);
  // OpenCV: one column per angle; its peak column is the angle of the strongest line.
  cv::Mat energy_cv(1, radon.cols, CV_64F);
  for (int k = 0; k < radon.cols; ++k) {
    cv::Mat col;
    radon.col(k).convertTo(col, CV_64F);
    energy_cv.at<double>(k) = col.dot(col);
  }
  cv::Point cv_peak;
  cv::minMaxLoc(energy_cv, nullptr, nullptr, nullptr, &cv_peak);
  const auto energy = radonLineEnergy(occupiedPoints(t), 0, kDeg, 180);
  const int ours = static_cast<int>(std::max_element(energy.begin(), energy.end()) - energy.begin());
  // OpenCV's image rows run downwards, ours upwards: its angle theta is our 180 - theta.
  const int diff = std::abs(ours - (180 - cv_peak.x) % 180) % 180;
  EXPECT_LE(std::min(diff, 180 - diff), 1) << "ours " << ours << " opencv " << cv_peak.x;
}

TEST(Radon, TuningRecoversASmallRotationError) {
  const std::vector<cv::Point2f> a = occupiedPoints(intelCrop());
  const double truth = 23.0 * kDeg, approx = truth - 1.3 * kDeg;
  // B is A turned by -truth; turning B by the approximate angle leaves 1.3 degrees to tune.
  const auto b = transformed(a, CellTransform{-truth, {400, 100}});
  const auto b_approx = transformed(b, CellTransform{approx, {0, 0}});
  const double delta = radonRotationTuning(a, b_approx, 3 * kDeg, 0.1 * kDeg);
  EXPECT_NEAR(approx + delta, truth, 0.15 * kDeg);
}

TEST(Radon, GlobalCandidatesContainTheTrueRotation) {
  const std::vector<cv::Point2f> a = occupiedPoints(intelCrop());
  for (double deg : {0.0, 57.0, 133.5, 250.0}) {
    const auto b = transformed(a, CellTransform{-deg * kDeg, {0, 0}});
    bool found = false;
    for (double alpha : globalRotationCandidates(a, b, kDeg, 4))
      for (double theta : {alpha, alpha + M_PI})
        found |= std::abs(std::remainder(theta - deg * kDeg, 2 * M_PI)) <= 1.0 * kDeg;
    EXPECT_TRUE(found) << deg;
  }
}

TEST(SimilarityIndex, PeaksAtTheTrueTranslationAndSearchFindsIt) {
  const cv::Mat t = intelCrop();
  const SimilarityIndex index(t, t, 0);
  const SimilarityCounts at_truth = index.evaluate({0, {0, 0}});
  EXPECT_DOUBLE_EQ(at_truth.acceptance(), 1.0);
  EXPECT_DOUBLE_EQ(at_truth.wallAgreement(), 1.0);
  EXPECT_GT(at_truth.J(), index.evaluate({0, {4, -3}}).J());
  EXPECT_GT(at_truth.J(), index.evaluate({2 * kDeg, {0, 0}}).J());
  const SearchResult found = index.search({0, {-6, 5}}, 10, 0.5 * kDeg, 2);
  EXPECT_NEAR(found.transform.t.x, 0, 1e-9);
  EXPECT_NEAR(found.transform.t.y, 0, 1e-9);
  EXPECT_NEAR(found.transform.theta, 0, 1e-9);
}

TEST(Verification, AcceptsTheTruthRejectsAWrongPoseAndAnotherBuilding) {
  const cv::Mat t = intelCrop();
  const SimilarityIndex same(t, t, 0);
  VerificationParams params;
  PoseFigures figures;  // distinct, unambiguous, nothing seen through, a short reach
  figures.smaller_map_walls = 1000.0;
  EXPECT_TRUE(verify(same.evaluate({0, {0, 0}}), 0.05, figures, params).accepted);
  const Verdict wrong = verify(same.evaluate({90 * kDeg, {300, 0}}), 0.05, figures, params);
  EXPECT_FALSE(wrong.accepted);
  const OccupancyGrid aces = loadMap(test::referenceMap("aces"));
  const cv::Mat other = toTernary(bench::cropGrid(aces, 400, 400, 300, 300));
  const SimilarityIndex different(t, other, 0);
  const SearchResult best = different.search({0, {0, 0}}, 20, kDeg, 3);
  const Verdict v = verify(best.counts, 0.05, figures, params);
  EXPECT_FALSE(v.accepted);
  EXPECT_FALSE(v.reason.empty());
  EXPECT_DOUBLE_EQ(fusedEntropyIncrease(same.evaluate({0, {0, 0}})), 0.0);
}

// A map sharing only a short stretch of wall with another that reaches far beyond it: the
// heading the stretch fixes carries to the far walls, and the pose is refused for it, as it is
// for a reach that cannot be measured (no shared wall).
TEST(Verification, ASharedStubThatFixesTooLittleOfTheMapIsRejected) {
  // A: one wall 40 cells long. B: the same wall and, 400 cells away, a room's worth of walls.
  cv::Mat a(600, 600, CV_8U, cv::Scalar(kFreeCell)), b = a.clone();
  cv::line(a, {100, 100}, {140, 100}, cv::Scalar(kOccupiedCell));
  cv::line(b, {100, 100}, {140, 100}, cv::Scalar(kOccupiedCell));
  cv::rectangle(b, {100, 480}, {160, 540}, cv::Scalar(kOccupiedCell));
  const SimilarityIndex index(a, b, 0);
  const double lever = index.lever({0, {0, 0}});
  // The shared wall's radius of gyration is 40 / sqrt(12) = 11.5 cells; most of B lies ~400
  // cells from it.
  EXPECT_GT(lever, 30.0);
  EXPECT_TRUE(std::isinf(index.lever({std::nan(""), {0, 0}}))) << "a pose that is not a number places nothing";
  // The same wall alone reaches no further than itself.
  const SimilarityIndex wall_only(a, a, 0);
  EXPECT_LT(wall_only.lever({0, {0, 0}}), 2.0);
  VerificationParams params;
  PoseFigures figures;
  figures.smaller_map_walls = 40;
  figures.lever = lever;
  const SimilarityCounts counts = wall_only.evaluate({0, {0, 0}});
  params.min_shared_wall_m = 0;  // the stub alone is judged here
  const Verdict v = verify(counts, 0.05, figures, params);
  EXPECT_FALSE(v.accepted);
  EXPECT_NE(v.reason.find("fix too little of the map"), std::string::npos) << v.reason;
  figures.lever = wall_only.lever({0, {0, 0}});
  EXPECT_TRUE(verify(counts, 0.05, figures, params).accepted) << verify(counts, 0.05, figures, params).reason;
  figures.lever = SimilarityIndex(a, cv::Mat(600, 600, CV_8U, cv::Scalar(kFreeCell)), 0).lever({0, {0, 0}});
  EXPECT_FALSE(verify(counts, 0.05, figures, params).accepted) << "a reach that cannot be measured passed";
}

TEST(CorrelationSearch, FindsAKnownTranslationAtAKnownRotation) {
  const cv::Mat a = downsampleTernary(downsampleTernary(toTernary(intel())));
  const CellTransform truth{70 * kDeg, {0, 0}};
  cv::Point2d offset;
  // B is A turned by -70 degrees: then A = R(70) (B - offset') for the canvas offset.
  const cv::Mat b = rotateTernary(a, -truth.theta, offset);
  const CellTransform b_to_a{truth.theta, -CellTransform{truth.theta, {0, 0}}.apply(offset)};
  const CorrelationSearch search(a, b, 10.0);
  // Asked at theta and at theta - pi (whose reflected half is theta): both must find it.
  for (const double asked : {truth.theta, truth.theta - M_PI}) {
    const auto candidates = search.candidates(asked, 3, 3);
    ASSERT_EQ(candidates.size(), 6u);
    const CellTransform& best = asked == truth.theta ? candidates[0] : candidates[3];
    EXPECT_NEAR(std::remainder(best.theta - truth.theta, 2 * M_PI), 0.0, 1e-9);
    EXPECT_LE(cv::norm(best.t - b_to_a.t), 1.5) << asked;
  }
}

TEST(ChamferPolish, RecoversASubCellMisalignment) {
  // A real crop against itself, started 0.4 degrees and 0.7 cells off: the polish must land
  // within a tenth of a cell and a few hundredths of a degree, closer than the similarity
  // index's one-cell tolerance can tell.
  const cv::Mat t = intelCrop();
  const ChamferPolish polish(t, t);
  const CellTransform start{0.4 * kDeg, {0.7, -0.5}};
  const CellTransform done = polish.polish(start);
  EXPECT_NEAR(done.theta, 0.0, 0.03 * kDeg);
  EXPECT_NEAR(done.t.x, 0.0, 0.1);
  EXPECT_NEAR(done.t.y, 0.0, 0.1);
  EXPECT_LT(polish.meanDistance(done), polish.meanDistance(start));
}

TEST(ChamferPolish, TruncatedDistanceIsExactBelowItsReach) {
  // Against OpenCV's exact Euclidean transform on a real crop: equal below the reach, capped
  // beyond it (the polish only reads distances below the reach).
  const cv::Mat t = intelCrop();
  cv::Mat exact;
  cv::distanceTransform(t != kOccupiedCell, exact, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const cv::Mat ours = truncatedWallDistance(t, 4.0);
  int near = 0;
  for (int r = 0; r < t.rows; ++r)
    for (int c = 0; c < t.cols; ++c) {
      const float e = exact.at<float>(r, c), o = ours.at<float>(r, c);
      if (e < 4.0f) {
        ++near;
        ASSERT_NEAR(o, e, 1e-3) << r << "," << c;
      } else {
        ASSERT_EQ(o, 4.0f) << r << "," << c;
      }
    }
  EXPECT_GT(near, 5000);  // the crop has walls to measure from
}

// The merge sums a large map a band of rows at a time; every cell, on either side of each
// band's edge, must be the log-odds sum of the cells the two maps have there.
TEST(GridMerge, MapsTallerThanOneBandMergeCellForCell) {
  const OccupancyGrid& a = intel();  // 761 rows: three bands
  const int shift_cols = 7, shift_rows = 300;
  const Pose2D shift{shift_cols * a.resolution, shift_rows * a.resolution, 0.0};
  const OccupancyGrid merged = mergeGrids(a, {{&a, shift}});
  // Merged cell (c, r) is cell (c + oc, r + or) of `a` (the bounds may gain a cell of rounding).
  const int oc = static_cast<int>(std::lround((merged.origin.x - a.origin.x) / a.resolution));
  const int or_ = static_cast<int>(std::lround((merged.origin.y - a.origin.y) / a.resolution));
  ASSERT_GE(merged.width, a.width + shift_cols);
  ASSERT_GE(merged.height, a.height + shift_rows);
  auto logit = [](int v) {
    const double p = std::clamp(v / 100.0, 0.02, 0.98);
    return static_cast<float>(std::log(p / (1.0 - p)));
  };
  auto known = [&](int c, int r) { return c >= 0 && r >= 0 && c < a.width && r < a.height && a.at(c, r) >= 0; };
  size_t both = 0;
  for (int r = 0; r < merged.height; ++r)
    for (int c = 0; c < merged.width; ++c) {
      const int ac = c + oc, ar = r + or_, bc = ac - shift_cols, br = ar - shift_rows;
      const bool in_a = known(ac, ar), in_b = known(bc, br);
      if (!in_a && !in_b) {
        ASSERT_EQ(merged.at(c, r), OccupancyGrid::kUnknown) << c << "," << r;
        continue;
      }
      float sum = 0.0f;
      if (in_a) sum += logit(a.at(ac, ar));
      if (in_b) sum += logit(a.at(bc, br));
      both += in_a && in_b;
      ASSERT_EQ(merged.at(c, r), static_cast<int8_t>(std::lround(100.0 / (1.0 + std::exp(-sum))))) << c << "," << r;
    }
  EXPECT_GT(both, 50000u);  // 68 662 cells both maps know
}

TEST(GridMerge, PlacesPiecesBackWhereTheyCameFrom) {
  const OccupancyGrid left = bench::cropGrid(intel(), 0, 0, 450, 761);
  const OccupancyGrid right_original = bench::cropGrid(intel(), 400, 0, 414, 761);
  const Pose2D frame{3.0, -7.0, 1.1};  // the right piece in a frame of its own
  const OccupancyGrid right = bench::reframeGrid(right_original, frame);
  const OccupancyGrid merged = mergeGrids(left, {{&right, frame}});
  // Every cell of the original the merge covers must be known again with the same state
  // (small aliasing from the rotation is allowed).
  size_t compared = 0, equal = 0;
  const Pose2D to_merged = merged.origin.inverse().compose(intel().origin);
  for (int r = 0; r < intel().height; r += 3)
    for (int c = 0; c < intel().width; c += 3) {
      const int v = intel().at(c, r);
      if (v < 0) continue;
      double x, y;
      to_merged.apply((c + 0.5) * 0.05, (r + 0.5) * 0.05, x, y);
      const int mc = static_cast<int>(x / 0.05), mr = static_cast<int>(y / 0.05);
      ASSERT_TRUE(mc >= 0 && mr >= 0 && mc < merged.width && mr < merged.height);
      const int m = merged.at(mc, mr);
      ++compared;
      equal += (m >= 65) == (v >= 65) && m >= 0;
    }
  EXPECT_GT(compared, 10000u);
  EXPECT_GT(double(equal) / compared, 0.97);
}
