#include "mrslam/fusion/wall_consistency.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {
namespace {

constexpr double kBehindWallCells = 3.0;        // how far behind a wall "seen through it" looks
constexpr size_t kMaxFreeCells = 15000;     // free cells sampled per map
constexpr size_t kMaxWallCells = 15000;     // wall cells sampled per map (the checks are shares)


CellTransform inverse(const CellTransform& x) {
  const double c = std::cos(x.theta), s = std::sin(x.theta);
  return {-x.theta, {-(c * x.t.x + s * x.t.y), s * x.t.x - c * x.t.y}};
}

// Centres of the nonzero cells of `mask`, every stride-th in raster order so that at most
// `max_points` are kept.
std::vector<cv::Point2f> cellCentres(const cv::Mat& mask, size_t max_points) {
  const size_t total = static_cast<size_t>(cv::countNonZero(mask));
  const size_t stride = total <= max_points ? 1 : (total + max_points - 1) / max_points;
  std::vector<cv::Point2f> out;
  out.reserve(total / stride + 1);
  size_t countdown = 1;
  for (int r = 0; r < mask.rows; ++r) {
    const uint8_t* row = mask.ptr<uint8_t>(r);
    for (int c = 0; c < mask.cols; ++c)
      if (row[c] && --countdown == 0) out.emplace_back(c + 0.5f, r + 0.5f), countdown = stride;
  }
  return out;
}

// The cell of `to` where point p of `from` lands, or false when it lands outside `to`.
bool land(const cv::Point2f& p, double c, double s, const cv::Point2d& t, const cv::Mat& to, int& x, int& y) {
  const double fx = std::floor(c * p.x - s * p.y + t.x), fy = std::floor(s * p.x + c * p.y + t.y);
  if (!(fx >= 0 && fy >= 0 && fx < to.cols && fy < to.rows)) return false;
  x = static_cast<int>(fx), y = static_cast<int>(fy);
  return true;
}

}  // namespace

WallConsistencyCheck::Side WallConsistencyCheck::makeSide(const cv::Mat& ternary) {
  Side side;
  side.ternary = ternary;
  side.walls = cellCentres(ternary == kOccupiedCell, kMaxWallCells);
  side.free = cellCentres(ternary == kFreeCell, kMaxFreeCells);
  return side;
}

bool WallConsistencyCheck::Side::wallWithin(int x, int y, const std::vector<cv::Point>& offsets) const {
  for (const cv::Point& d : offsets) {
    const int u = x + d.x, v = y + d.y;
    if (u >= 0 && v >= 0 && u < ternary.cols && v < ternary.rows && ternary.at<uint8_t>(v, u) == kOccupiedCell)
      return true;
  }
  return false;
}

namespace {
std::vector<cv::Point> offsetsWithin(double radius) {
  std::vector<cv::Point> out{{0, 0}};
  const int r = static_cast<int>(std::floor(radius));
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      if ((dx || dy) && dx * dx + dy * dy <= radius * radius) out.emplace_back(dx, dy);
  return out;
}
}  // namespace

WallConsistencyCheck::WallConsistencyCheck(const cv::Mat& ternary_a, const cv::Mat& ternary_b, double tolerance_cells)
    : a_(makeSide(ternary_a)), b_(makeSide(ternary_b)),
      tolerance_offsets_(offsetsWithin(tolerance_cells)), behind_offsets_(offsetsWithin(kBehindWallCells)) {}

WallConsistencyCheck::WallCounts WallConsistencyCheck::countWalls(const Side& from, const Side& to,
                                                                  const CellTransform& transform) const {
  WallCounts n;
  const double c = std::cos(transform.theta), s = std::sin(transform.theta);
  for (const cv::Point2f& p : from.walls) {
    int x, y;
    if (!land(p, c, s, transform.t, to.ternary, x, y)) continue;
    const uint8_t state = to.ternary.at<uint8_t>(y, x);
    const bool near = to.wallWithin(x, y, tolerance_offsets_);
    if (state == kUnknownCell && !near) continue;  // outside the other's known space
    n.known += 1;
    if (!near) {
      n.deep_free += state == kFreeCell;
      continue;
    }
    n.near += 1;
  }
  return n;
}

double WallConsistencyCheck::seenThrough(const Side& from, const Side& to, const CellTransform& transform) const {
  double near = 0, behind = 0;
  const double c = std::cos(transform.theta), s = std::sin(transform.theta);
  for (const cv::Point2f& p : from.free) {
    int x, y;
    if (!land(p, c, s, transform.t, to.ternary, x, y) || !to.wallWithin(x, y, behind_offsets_)) continue;
    near += 1;
    behind += to.ternary.at<uint8_t>(y, x) == kUnknownCell;
  }
  return near > 0 ? behind / near : 0.0;
}

WallConsistency WallConsistencyCheck::evaluate(const CellTransform& b_in_a) const {
  const CellTransform a_in_b = inverse(b_in_a);
  const WallCounts b = countWalls(b_, a_, b_in_a), a = countWalls(a_, b_, a_in_b);
  WallConsistency out;
  out.b_on_a = b.known > 0 ? b.near / b.known : 0.0;
  out.a_on_b = a.known > 0 ? a.near / a.known : 0.0;
  const double known = a.known + b.known;
  out.conflict = known > 0 ? (a.deep_free + b.deep_free) / known : 0.0;
  out.seen_through = std::max(seenThrough(b_, a_, b_in_a), seenThrough(a_, b_, a_in_b));
  return out;
}

}  // namespace mrslam::fusion
