// Stage 2: edge smoothing. A wall seen by a noisy laser appears in the grid as a band a few
// cells thick, so Canny returns two parallel edges C1 and C2 for one obstacle. The paper
// takes the middle curve P = C1 (+) C2 as the most probable obstacle location. We compute it
// for all edges at once: edges closer than d_t cells are joined (morphological closing with
// a disc of radius d_t) and the joined band is thinned to its one-cell-wide middle curve.
#pragma once

#include <opencv2/core.hpp>

namespace mrslam::fusion {

// `edges`: CV_8U 0/255. Returns the one-cell-wide middle curves (CV_8U 0/255).
cv::Mat smoothEdges(const cv::Mat& edges, int distance_threshold_cells);

// Zhang-Suen thinning of a binary image (CV_8U, 0/non-zero) to one-cell-wide curves; the same
// result as cv::ximgproc::thinning(THINNING_ZHANGSUEN) at a fraction of the cost on sparse images.
cv::Mat thinToMiddleCurves(const cv::Mat& binary);

}  // namespace mrslam::fusion
