#include "mrslam/map_io.h"

#include <yaml-cpp/yaml.h>
#include <zlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mrslam/atomic_file.h"

namespace mrslam {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const std::string& file, const std::string& what) {
  throw MapIoError(file + ": " + what);
}

template <typename T>
T readScalar(const YAML::Node& root, const char* key, const std::string& file) {
  const YAML::Node node = root[key];
  if (!node) fail(file, std::string("missing key '") + key + "'");
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    fail(file, std::string("key '") + key + "' has an invalid value");
  }
}

template <typename T>
T readScalarOr(const YAML::Node& root, const char* key, T fallback, const std::string& file) {
  return root[key] ? readScalar<T>(root, key, file) : fallback;
}

// The file must exist and be a regular file. A path the system will not look up (a name too
// long, a directory without permission) is refused by name too: the throwing std::filesystem
// calls once let a fuzzed yaml's image name abort the loader.
void requireFile(const fs::path& path, const std::string& missing, const std::string& not_a_file) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (status.type() == fs::file_type::not_found) fail(path.string(), missing);
  if (ec) fail(path.string(), "cannot be looked up (" + ec.message() + ")");
  if (!fs::is_regular_file(status)) fail(path.string(), not_a_file);
}

constexpr long long kMaxImageCells = 400LL * 1000 * 1000;  // as validateGrid's limit

// A PGM/PPM whose header claims more cells than any map has, or a binary one shorter than its
// header promises, is reported as such (OpenCV would only say it cannot read it, and print to
// stderr while doing so).
void checkPnmHeader(const std::string& path, const std::string& yaml_path) {
  std::ifstream in(path, std::ios::binary);
  char magic[2] = {0, 0};
  in.read(magic, 2);
  if (magic[0] != 'P' || magic[1] < '1' || magic[1] > '6') return;
  // P1 / P4 (bitmaps) have no maxval; OpenCV reads every one of the six.
  const bool bitmap = magic[1] == '1' || magic[1] == '4', ascii = magic[1] <= '3';
  long values[3] = {0, 0, 1};
  for (int k = 0; k < (bitmap ? 2 : 3); ++k) {
    in >> std::ws;
    while (in.peek() == '#') in.ignore(1 << 20, '\n'), in >> std::ws;
    if (!(in >> values[k]) || values[k] <= 0) fail(path, "malformed PNM header (image of " + yaml_path + ")");
  }
  if (values[2] > 65535) fail(path, "malformed PGM header: maxval " + std::to_string(values[2]) + " (image of " + yaml_path + ")");
  // Compared by division, so that no product of header values can overflow.
  if (values[0] > kMaxImageCells || values[1] > kMaxImageCells / values[0])
    fail(path, "image header claims " + std::to_string(values[0]) + " x " + std::to_string(values[1]) +
                   " cells, beyond the limit of " + std::to_string(kMaxImageCells) + " (image of " + yaml_path + ")");
  if (ascii) return;  // OpenCV reports a short one itself
  in.get();  // the single whitespace after the last header value
  const long long row_bytes = bitmap ? (values[0] + 7) / 8 : static_cast<long long>(values[0]) * (magic[1] == '6' ? 3 : 1);
  const long long expected = row_bytes * values[1] * (values[2] > 255 ? 2 : 1);
  const long long header = in.tellg();
  std::error_code ec;
  const long long size = static_cast<long long>(fs::file_size(path, ec));
  if (ec) fail(path, "cannot be read (" + ec.message() + ")");
  if (size - header < expected)
    fail(path, "image data truncated: header says " + std::to_string(values[0]) + " x " +
                   std::to_string(values[1]) + " cells, file holds " + std::to_string(size - header) +
                   " of " + std::to_string(expected) + " bytes (image of " + yaml_path + ")");
}

uint32_t bigEndian32(const unsigned char* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | uint32_t{p[3]};
}

// A PNG is checked chunk by chunk (lengths, CRCs, IHDR first, IEND present, the size IHDR
// claims) before libpng sees it: libpng reports what it cannot read on stderr, in lines of its
// own, and the contract of the tools is one line naming the file.
void checkPngStructure(const std::string& path, const std::string& yaml_path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  static const char kSignature[] = "\x89PNG\r\n\x1a\n";
  if (bytes.size() < 8 || bytes.compare(0, 8, kSignature, 8) != 0) return;  // not a PNG: OpenCV decides
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::string where = " (image of " + yaml_path + ")";
  size_t at = 8;
  bool first = true, end = false;
  while (!end) {
    if (at + 12 > bytes.size()) fail(path, "PNG truncated: chunk header at byte " + std::to_string(at) + where);
    const uint32_t length = bigEndian32(data + at);
    if (length > bytes.size() - at - 12) fail(path, "PNG truncated or corrupt: chunk of " + std::to_string(length) + " bytes at byte " + std::to_string(at) + where);
    const std::string type = bytes.substr(at + 4, 4);
    const uint32_t crc = bigEndian32(data + at + 8 + length);
    if (crc != crc32(0L, data + at + 4, length + 4)) fail(path, "PNG corrupt: bad CRC in chunk '" + type + "'" + where);
    if (first && type != "IHDR") fail(path, "PNG corrupt: the first chunk is not IHDR" + where);
    if (type == "IHDR") {
      if (length < 13) fail(path, "PNG corrupt: short IHDR" + where);
      const long long width = bigEndian32(data + at + 8), height = bigEndian32(data + at + 12);
      if (width == 0 || height == 0 || width > kMaxImageCells || height > kMaxImageCells / width)
        fail(path, "image header claims " + std::to_string(width) + " x " + std::to_string(height) +
                       " cells, beyond the limit of " + std::to_string(kMaxImageCells) + where);
    }
    end = type == "IEND";
    first = false;
    at += 12 + length;
  }
}

// Writes to `path` whatever `write` puts on the stream, whole or not at all (atomic_file.h).
template <typename Write>
void writeFile(const std::string& path, Write write) {
  try {
    writeFileAtomically(path, write);
  } catch (const std::runtime_error& e) {
    throw MapIoError(e.what());
  }
}

void writeBytes(std::ostream& out, const void* bytes, size_t size) {
  out.write(static_cast<const char*>(bytes), static_cast<std::streamsize>(size));
}

// map_saver's trinary rule: >= 65 occupied (0), <= 25 free (254), else unknown (205).
uint8_t trinaryPixel(int v) { return v < 0 ? 205 : (v >= 65 ? 0 : (v <= 25 ? 254 : 205)); }

// The image's row `image_row` (top row first, as images are stored).
void trinaryRow(const OccupancyGrid& grid, int image_row, uint8_t* out) {
  const int r = grid.height - 1 - image_row;
  for (int c = 0; c < grid.width; ++c) out[c] = trinaryPixel(grid.at(c, r));
}

// A binary PGM written a row at a time, byte for byte what OpenCV writes: the image is never
// held whole (Freiburg campus's 31 M cells were held three times over while being written).
void writePgm(const OccupancyGrid& grid, const std::string& path) {
  writeFile(path, [&grid](std::ostream& out) {
    out << "P5\n" << grid.width << ' ' << grid.height << "\n255\n";
    std::vector<uint8_t> row(grid.width);
    for (int k = 0; k < grid.height && out; ++k) {
      trinaryRow(grid, k, row.data());
      writeBytes(out, row.data(), row.size());
    }
  });
}

void writePng(const OccupancyGrid& grid, const std::string& path) {
  std::vector<uchar> encoded;
  {
    cv::Mat image(grid.height, grid.width, CV_8U);
    for (int k = 0; k < grid.height; ++k) trinaryRow(grid, k, image.ptr<uint8_t>(k));
    try {
      if (!cv::imencode(".png", image, encoded)) fail(path, "cannot encode image");
    } catch (const cv::Exception& e) {
      fail(path, std::string("cannot encode image: ") + e.what());
    }
  }
  writeFile(path, [&encoded](std::ostream& out) { writeBytes(out, encoded.data(), encoded.size()); });
}

}  // namespace

OccupancyGrid loadMap(const std::string& yaml_path) {
  requireFile(yaml_path, "no such file", "not a file (a map yaml was expected)");
  YAML::Node root;
  try {
    root = YAML::LoadFile(yaml_path);
  } catch (const YAML::Exception& e) {
    fail(yaml_path, std::string("malformed yaml: ") + e.what());
  }
  if (!root.IsMap()) fail(yaml_path, "malformed yaml: expected a mapping of map_server keys");

  const auto image_name = readScalar<std::string>(root, "image", yaml_path);
  const auto resolution = readScalar<double>(root, "resolution", yaml_path);
  if (!(resolution > 0.0) || !std::isfinite(resolution))
    fail(yaml_path, "resolution must be a positive finite number");
  const YAML::Node origin = root["origin"];
  if (!origin || !origin.IsSequence() || origin.size() != 3)
    fail(yaml_path, "origin must be a list [x, y, yaw]");
  Pose2D origin_pose;
  try {
    origin_pose = {origin[0].as<double>(), origin[1].as<double>(), origin[2].as<double>()};
  } catch (const YAML::Exception&) {
    fail(yaml_path, "origin must hold three numbers");
  }
  if (!std::isfinite(origin_pose.x) || !std::isfinite(origin_pose.y) ||
      !std::isfinite(origin_pose.yaw))
    fail(yaml_path, "origin must be finite");
  const int negate = readScalarOr<int>(root, "negate", 0, yaml_path);
  const double occ_th = readScalarOr<double>(root, "occupied_thresh", 0.65, yaml_path);
  const double free_th = readScalarOr<double>(root, "free_thresh", 0.196, yaml_path);
  if (!(free_th >= 0.0 && free_th < occ_th && occ_th <= 1.0))
    fail(yaml_path, "thresholds must satisfy 0 <= free_thresh < occupied_thresh <= 1");
  const auto mode = readScalarOr<std::string>(root, "mode", "trinary", yaml_path);
  if (mode != "trinary" && mode != "scale" && mode != "raw")
    fail(yaml_path, "mode must be trinary, scale or raw (got '" + mode + "')");

  fs::path image_path(image_name);
  if (image_path.is_relative()) image_path = fs::path(yaml_path).parent_path() / image_path;
  requireFile(image_path, "image named in " + yaml_path + " not found", "not a file (image of " + yaml_path + ")");
  checkPnmHeader(image_path.string(), yaml_path);
  checkPngStructure(image_path.string(), yaml_path);
  // OpenCV throws for what its decoders refuse outright (an image taller or wider than 2^20
  // pixels, found by fuzz_map_loader: it aborted the loader): refused by name like the rest.
  cv::Mat image;
  try {
    image = cv::imread(image_path.string(), cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    fail(image_path.string(), "unreadable image: OpenCV refuses it (" + e.err + ") (image of " + yaml_path + ")");
  }
  if (image.empty()) fail(image_path.string(), "unreadable image (image of " + yaml_path + ")");
  if (image.depth() != CV_8U) fail(image_path.string(), "only 8-bit images are supported");

  // map_server averages the colour channels; an alpha channel of 0 marks unknown (scale mode).
  cv::Mat alpha;
  if (image.channels() == 4) cv::extractChannel(image, alpha, 3);
  if (image.channels() >= 3) {
    cv::Mat bgr = image;
    if (image.channels() == 4) cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
    cv::Mat grey(bgr.size(), CV_8U);
    for (int r = 0; r < bgr.rows; ++r)
      for (int c = 0; c < bgr.cols; ++c) {
        const auto& p = bgr.at<cv::Vec3b>(r, c);
        grey.at<uint8_t>(r, c) = static_cast<uint8_t>((p[0] + p[1] + p[2]) / 3);
      }
    image = grey;
  } else if (image.channels() == 2) {
    cv::extractChannel(image, alpha, 1);
    cv::extractChannel(image, image, 0);
  }

  const bool raw = mode == "raw", scale = mode == "scale";
  OccupancyGrid grid;
  grid.width = image.cols;
  grid.height = image.rows;
  grid.resolution = resolution;
  grid.origin = origin_pose;
  grid.data.resize(static_cast<size_t>(grid.width) * grid.height);
  for (int r = 0; r < image.rows; ++r) {
    const uint8_t* row = image.ptr<uint8_t>(r);
    const int grid_row = grid.height - 1 - r;  // image row 0 is the top of the map
    for (int c = 0; c < image.cols; ++c) {
      int8_t& cell = grid.at(c, grid_row);
      const int v = row[c];
      if (raw) {
        cell = v > 100 ? OccupancyGrid::kUnknown : static_cast<int8_t>(v);
        continue;
      }
      if (scale && !alpha.empty() && alpha.at<uint8_t>(r, c) == 0) {
        cell = OccupancyGrid::kUnknown;
        continue;
      }
      const double p = negate ? v / 255.0 : (255.0 - v) / 255.0;
      if (p > occ_th) {
        cell = 100;
      } else if (p < free_th) {
        cell = 0;
      } else if (scale) {
        cell = static_cast<int8_t>(std::lround(99.0 * (p - free_th) / (occ_th - free_th)));
      } else {
        cell = OccupancyGrid::kUnknown;
      }
    }
  }
  const std::string invalid = validateGrid(grid);
  if (!invalid.empty()) fail(yaml_path, invalid);
  return grid;
}

void saveMap(const OccupancyGrid& grid, const std::string& yaml_path,
             const std::string& image_extension) {
  const std::string why = validateGrid(grid);
  if (!why.empty()) fail(yaml_path, "refusing to write an invalid grid: " + why);
  if (image_extension != ".pgm" && image_extension != ".png")
    fail(yaml_path, "image extension must be .pgm or .png");

  const fs::path yaml(yaml_path);
  fs::path image_path = yaml;
  image_path.replace_extension(image_extension);
  if (image_extension == ".pgm")
    writePgm(grid, image_path.string());
  else
    writePng(grid, image_path.string());
  std::ostringstream yaml_text;
  yaml_text.precision(17);
  yaml_text << "image: " << image_path.filename().string() << "\n"
            << "resolution: " << grid.resolution << "\n"
            << "origin: [" << grid.origin.x << ", " << grid.origin.y << ", " << grid.origin.yaw << "]\n"
            << "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  const std::string text = yaml_text.str();
  writeFile(yaml_path, [&text](std::ostream& out) { out << text; });
}

}  // namespace mrslam
