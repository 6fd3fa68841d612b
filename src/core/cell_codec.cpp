#include "mrslam/cell_codec.h"

#include <zlib.h>

#include <limits>
#include <stdexcept>

namespace mrslam {

std::vector<uint8_t> compressCells(const int8_t* cells, size_t count, int level) {
  if (count > std::numeric_limits<uLong>::max() / 2) throw std::invalid_argument("grid too large to compress");
  uLongf size = compressBound(static_cast<uLong>(count));
  std::vector<uint8_t> out(size);
  if (compress2(out.data(), &size, reinterpret_cast<const Bytef*>(cells), static_cast<uLong>(count), level) != Z_OK)
    throw std::runtime_error("zlib could not compress the grid");
  out.resize(size);
  out.shrink_to_fit();  // resize keeps compressBound's capacity, about the cells' own size
  return out;
}

std::string decompressCells(const uint8_t* data, size_t size, size_t expected_cells, std::vector<int8_t>& cells) {
  if (size > std::numeric_limits<uInt>::max() || expected_cells > std::numeric_limits<uInt>::max())
    return "compressed grid too large";
  cells.assign(expected_cells, 0);
  z_stream stream{};
  if (inflateInit(&stream) != Z_OK) return "zlib could not start";
  stream.next_in = const_cast<Bytef*>(data);
  stream.avail_in = static_cast<uInt>(size);
  stream.next_out = reinterpret_cast<Bytef*>(cells.data());
  stream.avail_out = static_cast<uInt>(expected_cells);
  const int status = inflate(&stream, Z_FINISH);
  const size_t produced = expected_cells - stream.avail_out;
  inflateEnd(&stream);
  // Z_STREAM_END with the output exactly full: the stream held exactly the grid.
  if (status == Z_STREAM_END && produced == expected_cells) return "";
  cells.clear();
  if (status == Z_STREAM_END) return "compressed grid holds " + std::to_string(produced) + " cells, not " + std::to_string(expected_cells);
  if (status == Z_BUF_ERROR && stream.avail_out == 0) return "compressed grid holds more than " + std::to_string(expected_cells) + " cells";
  if (status == Z_BUF_ERROR) return "compressed grid ends early";
  return "compressed grid is corrupt (zlib error " + std::to_string(status) + ")";
}

}  // namespace mrslam
