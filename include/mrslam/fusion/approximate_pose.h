// Stage 6: approximate relative pose from two matched segments. A line is fitted to each
// segment; the difference of their directions is the approximate rotation (eq. 12), and the
// difference of the centroids after rotating segment B is the approximate translation
// (eq. 13). A fitted line has no sense of direction, so both alpha and alpha + pi are
// returned and left to the verification to choose.
#pragma once

#include <array>

#include "mrslam/fusion/cell_transform.h"
#include "mrslam/fusion/segment.h"

namespace mrslam::fusion {

std::array<CellTransform, 2> approximatePose(const Segment& segment_a, const Segment& segment_b);

}  // namespace mrslam::fusion
