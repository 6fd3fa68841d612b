#include "mrslam/bench/multi_run_pairs.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <stdexcept>

namespace mrslam::bench {
namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Rigid least squares (2D Kabsch): the pose taking points b onto points a.
Pose2D kabsch(const MultiRunPair& p) {
  const size_t n = p.ax.size();
  double max = 0, may = 0, mbx = 0, mby = 0;
  for (size_t i = 0; i < n; ++i) max += p.ax[i], may += p.ay[i], mbx += p.bx[i], mby += p.by[i];
  max /= n, may /= n, mbx /= n, mby /= n;
  double sxx = 0, sxy = 0;  // sum of dot and cross products of the centred points
  for (size_t i = 0; i < n; ++i) {
    const double ux = p.bx[i] - mbx, uy = p.by[i] - mby, vx = p.ax[i] - max, vy = p.ay[i] - may;
    sxx += ux * vx + uy * vy;
    sxy += ux * vy - uy * vx;
  }
  const double yaw = std::atan2(sxy, sxx), c = std::cos(yaw), s = std::sin(yaw);
  return {max - (c * mbx - s * mby), may - (s * mbx + c * mby), yaw};
}

}  // namespace

OccupancyGrid loadRunMap(const std::string& png_path, double resolution) {
  const cv::Mat image = cv::imread(png_path, cv::IMREAD_GRAYSCALE);
  if (image.empty()) throw std::runtime_error(png_path + ": cannot read the image");
  OccupancyGrid g;
  g.width = image.cols, g.height = image.rows, g.resolution = resolution;
  g.data.resize(static_cast<size_t>(g.width) * g.height);
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c) {
      const uint8_t v = image.at<uint8_t>(g.height - 1 - r, c);  // grid row 0 is the bottom
      g.at(c, r) = v < 64 ? 100 : (v > 191 ? 0 : OccupancyGrid::kUnknown);
    }
  return g;
}

std::vector<MultiRunPair> readMultiRunPairs(const std::string& dir, double resolution) {
  const std::string path = dir + "/correspondences.csv";
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot read");
  std::map<std::pair<std::string, std::string>, MultiRunPair> by_pair;
  std::vector<std::pair<std::string, std::string>> order;
  std::string line;
  std::getline(in, line);  // header
  for (int number = 2; std::getline(in, line); ++number) {
    std::stringstream row(line);
    std::string a, b, field;
    double v[4];
    bool ok = static_cast<bool>(std::getline(row, a, ',')) && static_cast<bool>(std::getline(row, b, ','));
    for (double& x : v) {
      ok = ok && static_cast<bool>(std::getline(row, field, ','));
      try { if (ok) x = std::stod(field); } catch (const std::exception&) { ok = false; }
    }
    if (!ok) throw std::runtime_error(path + ":" + std::to_string(number) + ": malformed row");
    const auto key = std::make_pair(a, b);
    if (!by_pair.count(key)) order.push_back(key);
    MultiRunPair& p = by_pair[key];
    p.map_a = a, p.map_b = b;
    // Cell (col, row) covers [col, col + 1) x [row, row + 1) cells from the origin.
    p.ax.push_back((v[0] + 0.5) * resolution), p.ay.push_back((v[1] + 0.5) * resolution);
    p.bx.push_back((v[2] + 0.5) * resolution), p.by.push_back((v[3] + 0.5) * resolution);
  }
  std::vector<MultiRunPair> pairs;
  for (const auto& key : order) {
    MultiRunPair p = by_pair[key];
    if (p.ax.size() < 3) continue;  // too few corners for a truth
    p.truth = kabsch(p);
    std::vector<double> residual;
    for (size_t i = 0; i < p.ax.size(); ++i) {
      double x, y;
      p.truth.apply(p.bx[i], p.by[i], x, y);
      residual.push_back(std::hypot(x - p.ax[i], y - p.ay[i]) / resolution);
    }
    p.truth_residual_cells = median(residual);
    pairs.push_back(std::move(p));
  }
  return pairs;
}

MultiRunJudgement judgeMultiRun(const MultiRunPair& p, const Pose2D& estimate, double resolution) {
  MultiRunJudgement j;
  j.yaw_err_deg = std::abs(Pose2D::normalizeAngle(estimate.yaw - p.truth.yaw)) * 180 / M_PI;
  std::vector<double> err;
  for (size_t i = 0; i < p.bx.size(); ++i) {
    double ex, ey, tx, ty;
    estimate.apply(p.bx[i], p.by[i], ex, ey);
    p.truth.apply(p.bx[i], p.by[i], tx, ty);
    err.push_back(std::hypot(ex - tx, ey - ty) / resolution);
  }
  j.corner_err_cells = median(err);
  j.tolerance_cells = std::max(10.0, 2 * p.truth_residual_cells);
  j.correct = j.yaw_err_deg <= 2.0 && j.corner_err_cells <= j.tolerance_cells;
  return j;
}

}  // namespace mrslam::bench
