// One key for a cell (x, y) of an unbounded grid kept in a hash map (the benchmarks' sparse
// grids): x in the high 32 bits, y in the low.
#pragma once

#include <cstdint>

namespace mrslam::bench {

inline int64_t cellKey(int64_t x, int64_t y) {
  return static_cast<int64_t>((static_cast<uint64_t>(x) << 32) ^ static_cast<uint32_t>(y));
}

}  // namespace mrslam::bench
