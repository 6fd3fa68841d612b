#include "mrslam/slam/grid_indexed_points_map.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <mrpt/poses/CPose2D.h>

namespace mrslam::slam {

void GridIndexedPointsMap::index() {
  mark_as_modified();  // MRPT's cached bounding box
  grid_.build(m_x.data(), m_y.data(), m_x.size(), kCell);
  indexed_points_ = m_x.size();
}

void GridIndexedPointsMap::determineMatching2D(const mrpt::maps::CMetricMap* other_map,
                                               const mrpt::poses::CPose2D& other_pose,
                                               mrpt::tfest::TMatchingPairList& pairs,
                                               const mrpt::maps::TMatchingParams& params,
                                               mrpt::maps::TMatchingExtraResults& extra) const {
  extra = mrpt::maps::TMatchingExtraResults();
  pairs.clear();
  const auto* other = dynamic_cast<const mrpt::maps::CPointsMap*>(other_map);
  if (!other || other->empty() || empty() || params.decimation_other_map_points == 0) return;
  if (indexed_points_ != size()) throw std::logic_error("GridIndexedPointsMap: points changed without index()");
  const auto& ox = other->getPointsBufferRef_x();
  const auto& oy = other->getPointsBufferRef_y();
  const auto& oz = other->getPointsBufferRef_z();
  const float c = static_cast<float>(std::cos(other_pose.phi())), s = static_cast<float>(std::sin(other_pose.phi()));
  const float tx = static_cast<float>(other_pose.x()), ty = static_cast<float>(other_pose.y());
  // Every point moved into our frame (all of them, as MRPT's box rule takes them all), in
  // MRPT's order of operations so that both see the same moved point to the bit.
  std::vector<float> xs(ox.size()), ys(ox.size());
  for (size_t i = 0; i < ox.size(); ++i) {
    xs[i] = tx + c * ox[i] - s * oy[i];
    ys[i] = ty + s * ox[i] + c * oy[i];
  }
  const auto [x_min, x_max] = std::minmax_element(xs.begin(), xs.end());
  const auto [y_min, y_max] = std::minmax_element(ys.begin(), ys.end());
  const auto ours = boundingBox();
  if (*x_min > ours.max.x || *x_max < ours.min.x || *y_min > ours.max.y || *y_max < ours.min.y) return;
  // MRPT's angular term widens the pairing distance with the point's range from this pivot.
  const double pivot_x = params.angularDistPivotPoint.x, pivot_y = params.angularDistPivotPoint.y;
  float sum_sq = 0;  // summed in float, as MRPT sums it
  size_t paired = 0;
  pairs.reserve(other->size() / params.decimation_other_map_points + 1);
  for (size_t i = params.offset_other_map_points; i < other->size(); i += params.decimation_other_map_points) {
    const float x = xs[i], y = ys[i];
    const double reach = params.maxAngularDistForCorrespondence == 0
                             ? params.maxDistForCorrespondence
                             : params.maxAngularDistForCorrespondence * std::hypot(pivot_x - x, pivot_y - y) +
                                   params.maxDistForCorrespondence;
    // A hair wider for the grid, so that rounding never drops a pair the exact test keeps.
    const auto nearest = grid_.nearest(x, y, static_cast<float>(reach) * 1.0001f + 1e-6f);
    if (nearest.index < 0 || !(nearest.dist_sq < reach * reach)) continue;
    const auto j = static_cast<size_t>(nearest.index);
    mrpt::tfest::TMatchingPair& p = pairs.emplace_back(static_cast<uint32_t>(j), static_cast<uint32_t>(i), m_x[j],
                                                       m_y[j], m_z[j], ox[i], oy[i], oz[i]);
    p.errorSquareAfterTransformation = nearest.dist_sq;
    sum_sq += nearest.dist_sq;
    ++paired;
  }
  if (params.onlyUniqueRobust) {
    mrpt::tfest::TMatchingPairList all;
    all.swap(pairs);
    all.filterUniqueRobustPairs(size(), pairs);
  }
  extra.sumSqrDist = paired ? static_cast<float>(sum_sq / static_cast<double>(paired)) : 0.0f;
  // As MRPT counts it: paired points over all points, scaled back up by the decimation.
  extra.correspondencesRatio = static_cast<float>(params.decimation_other_map_points * paired) /
                               static_cast<float>(other->size());
}

}  // namespace mrslam::slam
