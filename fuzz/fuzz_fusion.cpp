// libFuzzer target: the fusion's entry. Two small grids are made from the input (sizes,
// resolutions, origins and cells from its bytes); whatever fusionInputProblem lets through must
// fuse without a crash, a hang or a non-finite accepted pose.
#include <cmath>
#include <cstdint>
#include <cstring>

#include "mrslam/fusion/map_fusion.h"

namespace {

struct Reader {
  const uint8_t* data;
  size_t size, at = 0;
  uint8_t byte() { return at < size ? data[at++] : 0; }
  double real() {  // any double, including NaN and inf
    double v = 0;
    uint8_t b[8];
    for (uint8_t& x : b) x = byte();
    std::memcpy(&v, b, sizeof v);
    return v;
  }
};

mrslam::OccupancyGrid grid(Reader& in) {
  mrslam::OccupancyGrid g;
  g.width = 8 + in.byte() % 120;
  g.height = 8 + in.byte() % 120;
  g.resolution = (in.byte() & 1) ? in.real() : 0.05 * (1 + in.byte() % 4);
  g.origin = {(in.byte() & 1) ? in.real() : 0.0, 0.0, (in.byte() & 1) ? in.real() : 0.0};
  g.data.resize(static_cast<size_t>(g.width) * g.height);
  for (int8_t& v : g.data) {
    const uint8_t b = in.byte();
    v = b < 80 ? -1 : (b < 200 ? 0 : (b < 250 ? 100 : static_cast<int8_t>(b)));  // 250..255: out of range
  }
  return g;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Reader in{data, size};
  const mrslam::OccupancyGrid a = grid(in), b = grid(in);
  mrslam::fusion::FusionParams params;
  params.use_segments = (in.byte() & 1) != 0;
  if (!mrslam::fusion::fusionInputProblem(a, b, params).empty()) return 0;
  const mrslam::fusion::FusionResult r = mrslam::fusion::alignMaps(a, b, params);
  if (r.accepted && !(std::isfinite(r.pose.x) && std::isfinite(r.pose.y) && std::isfinite(r.pose.yaw))) __builtin_trap();
  return 0;
}
