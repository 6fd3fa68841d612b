#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/poses/CPosePDFSOG.h>
#include <mrpt/slam/CGridMapAligner.h>

#include <chrono>

#include "mrslam/bench/peers.h"

namespace mrslam::bench {
namespace {

mrpt::maps::COccupancyGridMap2D toMrpt(const OccupancyGrid& g) {
  // Our bench maps have axis-aligned origins (yaw 0), which MRPT grids require.
  mrpt::maps::COccupancyGridMap2D m;
  const float res = static_cast<float>(g.resolution);
  m.setSize(g.origin.x, g.origin.x + g.width * g.resolution, g.origin.y, g.origin.y + g.height * g.resolution,
            res, 0.5f);
  const int w = std::min<int>(g.width, m.getSizeX()), h = std::min<int>(g.height, m.getSizeY());
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const int v = g.at(c, r);
      m.setCell(c, r, v < 0 ? 0.5f : 1.0f - v / 100.0f);  // MRPT cells hold P(free)
    }
  return m;
}

}  // namespace

PeerResult alignWithMrpt(const OccupancyGrid& a, const OccupancyGrid& b) {
  const auto start = std::chrono::steady_clock::now();
  PeerResult out;
  const auto ma = toMrpt(a), mb = toMrpt(b);
  mrpt::slam::CGridMapAligner aligner;
  aligner.setMinLoggingLevel(mrpt::system::LVL_ERROR);
  aligner.options.methodSelection = mrpt::slam::CGridMapAligner::amModifiedRANSAC;
  try {
    // No TReturnInfo out-parameter: passing one crashes in Debian's build.
    const auto pdf = aligner.AlignPDF(&ma, &mb, mrpt::poses::CPosePDFGaussian());
    const auto sog = std::dynamic_pointer_cast<mrpt::poses::CPosePDFSOG>(pdf);
    if (sog && sog->size() > 0) {
      mrpt::poses::CPose2D mean;
      mrpt::math::CMatrixDouble33 cov;
      sog->getMostLikelyCovarianceAndMean(cov, mean);
      out.accepted = true;
      out.pose = {mean.x(), mean.y(), mean.phi()};
    }
  } catch (const std::exception&) {
    out.accepted = false;  // MRPT throws when it finds too few features: a rejection
  }
  out.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace mrslam::bench
