// Lossless compression of an occupancy grid's cells for the inter-robot link
// (mrslam/CompressedMapShare): zlib (RFC 1950) of the row-major int8 cells. A SLAM grid is
// mostly unknown (-1) and free (0) in long runs, so it shrinks many times over.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace mrslam {

// The zlib stream of `count` cells. `level` 1 (fast) .. 9 (small).
std::vector<uint8_t> compressCells(const int8_t* cells, size_t count, int level);

// Inflates `size` bytes into exactly `expected_cells` cells, allocating no more than that
// (a peer's stream that would inflate further, or to less, is refused). Empty on success,
// else why the stream cannot be used.
std::string decompressCells(const uint8_t* data, size_t size, size_t expected_cells, std::vector<int8_t>& cells);

}  // namespace mrslam
