#include "mrslam/fusion/see_through.h"

#include <algorithm>
#include <cmath>

#include "mrslam/fusion/ternary_image.h"

namespace mrslam::fusion {
namespace {

constexpr int kBehindWallCells = 3;      // how far behind a wall "seen through it" looks
constexpr size_t kMaxFreeCells = 15000;  // free cells sampled per map (the check is a share)

CellTransform inverse(const CellTransform& x) {
  const double c = std::cos(x.theta), s = std::sin(x.theta);
  return {-x.theta, {-(c * x.t.x + s * x.t.y), s * x.t.x - c * x.t.y}};
}

}  // namespace

SeeThroughCheck::Side SeeThroughCheck::makeSide(const cv::Mat& ternary) {
  // Every stride-th free cell in raster order, so that at most kMaxFreeCells are kept.
  const size_t total = static_cast<size_t>(countCells(ternary, kFreeCell));
  const size_t stride = total <= kMaxFreeCells ? 1 : (total + kMaxFreeCells - 1) / kMaxFreeCells;
  return {ternary, everyStridethCell(ternary, kFreeCell, stride)};
}

bool SeeThroughCheck::Side::wallNear(int x, int y) const {
  const int r = kBehindWallCells;
  for (int dy = -r; dy <= r; ++dy) {
    const int v = y + dy;
    if (v < 0 || v >= ternary.rows) continue;
    const uint8_t* row = ternary.ptr<uint8_t>(v);
    for (int dx = -r; dx <= r; ++dx) {
      const int u = x + dx;
      if (u >= 0 && u < ternary.cols && dx * dx + dy * dy <= r * r && row[u] == kOccupiedCell) return true;
    }
  }
  return false;
}

SeeThroughCheck::SeeThroughCheck(const cv::Mat& ternary_a, const cv::Mat& ternary_b)
    : a_(makeSide(ternary_a)), b_(makeSide(ternary_b)) {}

double SeeThroughCheck::behindWalls(const Side& from, const Side& to, const CellTransform& transform) {
  double near = 0, behind = 0;
  const double c = std::cos(transform.theta), s = std::sin(transform.theta);
  for (const cv::Point2f& p : from.free) {
    const double fx = std::floor(c * p.x - s * p.y + transform.t.x), fy = std::floor(s * p.x + c * p.y + transform.t.y);
    if (!(fx >= 0 && fy >= 0 && fx < to.ternary.cols && fy < to.ternary.rows)) continue;
    const int x = static_cast<int>(fx), y = static_cast<int>(fy);
    if (!to.wallNear(x, y)) continue;
    near += 1;
    behind += to.ternary.at<uint8_t>(y, x) == kUnknownCell;
  }
  return near > 0 ? behind / near : 0.0;
}

double SeeThroughCheck::seenThrough(const CellTransform& b_in_a) const {
  return std::max(behindWalls(b_, a_, b_in_a), behindWalls(a_, b_, inverse(b_in_a)));
}

}  // namespace mrslam::fusion
