// Stage 7: rotation tuning with the Radon transform.
//
// The Radon transform R(theta, rho) of a map's obstacle image counts the obstacle cells on
// the line x cos(theta) + y sin(theta) = rho. Straight walls make sharp peaks at the angle
// of their normal. Obstacle images are sparse, so we compute R directly from the list of
// obstacle cells (cost: cells x angles) instead of rotating the whole image once per angle
// as cv::ximgproc::RadonTransform does; a unit test checks both agree on the peak angle.
//
// The "line energy" E(theta) = sum_rho R(theta, rho)^2 / N summarises how much of the map
// lies on lines at angle theta. E is invariant to translation, and rotating a map by alpha
// shifts E by alpha (mod 180 degrees).
#pragma once

#include <opencv2/core.hpp>
#include <vector>

namespace mrslam::fusion {

// E(theta_k) for theta_k = start + k * step, k = 0..count-1 (radians).
std::vector<double> radonLineEnergy(const std::vector<cv::Point2f>& points, double start,
                                    double step, int count);

// The paper's tuning (eq. 15): with map B already rotated by the approximate angle, find the
// small correction delta (|delta| <= window) that best lines up the Radon peaks of B with
// those of A. We compare the whole energy curves near the peaks (cross-correlation over
// delta) rather than single maxima, so a wall that only one map sees cannot decide alone.
double radonRotationTuning(const std::vector<cv::Point2f>& points_a,
                           const std::vector<cv::Point2f>& points_b_rotated, double window,
                           double step);

// The same, with map A's part (its strongest directions and fine spectra around them)
// computed once for many hypotheses about B.
class RadonTuner {
 public:
  // `peaks`: how many of A's strongest line directions take part.
  RadonTuner(const std::vector<cv::Point2f>& points_a, double window, double step, int peaks = 8);
  double tune(const std::vector<cv::Point2f>& points_b_rotated) const;

 private:
  struct Peak {
    double centre;
    std::vector<double> energy_a;  // +- window around centre
  };
  std::vector<Peak> peaks_;
  double step_;
  int half_;
};

// Our extension for unknown initial rotation (0-360 degrees): the circular cross-correlation
// of the two maps' line-energy spectra over all rotations, returning the `count` strongest
// local maxima alpha in [0, pi). Each alpha stands for two rotations, alpha and alpha + pi.
std::vector<double> globalRotationCandidates(const std::vector<cv::Point2f>& points_a,
                                             const std::vector<cv::Point2f>& points_b,
                                             double step, int count);

// Obstacle cells of a ternary image as points (cell centres, in cell units).
std::vector<cv::Point2f> occupiedPoints(const cv::Mat& ternary);

}  // namespace mrslam::fusion
