// Map I/O: map_server semantics (row order, origin, thresholds, negate, scale), round trips
// and clear errors on bad files.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <opencv2/imgcodecs.hpp>

#include "mrslam/atomic_file.h"
#include "mrslam/map_io.h"
#include "test_data.h"

namespace fs = std::filesystem;
using namespace mrslam;

namespace {

// Inside the test process's own scratch folder (test_main.cpp), which is removed at the end.
fs::path tempDir() {
  fs::path dir = fs::path(::testing::TempDir()) / "map_io";
  fs::create_directories(dir);
  return dir;
}

void writeText(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

std::string loadError(const fs::path& yaml) {
  try {
    loadMap(yaml.string());
  } catch (const MapIoError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(MapIo, ReadsReferenceMapWithMapServerRowOrderAndOrigin) {
  const OccupancyGrid g = loadMap(test::referenceMap("intel"));
  EXPECT_EQ(g.width, 814);
  EXPECT_EQ(g.height, 761);
  EXPECT_DOUBLE_EQ(g.resolution, 0.05);
  EXPECT_NEAR(g.origin.x, -20.888508584176403, 1e-12);
  EXPECT_NEAR(g.origin.y, -24.239226447458872, 1e-12);
  // Image row 0 is the top of the map: it must land in the grid's last row.
  const cv::Mat image = cv::imread(test::dataPath("maps/reference/intel.pgm"), cv::IMREAD_GRAYSCALE);
  int checked = 0;
  for (int c = 0; c < image.cols; ++c) {
    const int v = image.at<uint8_t>(0, c);
    const int8_t expected = v == 0 ? 100 : (v == 254 || v == 255 ? 0 : -1);
    EXPECT_EQ(g.at(c, g.height - 1), expected);
    const int bottom = image.at<uint8_t>(image.rows - 1, c);
    EXPECT_EQ(g.at(c, 0), bottom == 0 ? 100 : (bottom >= 254 ? 0 : -1));
    ++checked;
  }
  EXPECT_EQ(checked, 814);
  size_t occupied = 0, free = 0;
  for (int8_t v : g.data) occupied += v == 100, free += v == 0;
  EXPECT_GT(occupied, 10000u);
  EXPECT_GT(free, 100000u);
}

TEST(MapIo, ReadsRobotBuiltPngAndCoarseResolution) {
  const OccupancyGrid willow = loadMap(test::robotMap("willow-2010-02-18-0.10"));
  EXPECT_EQ(willow.width, 566);
  EXPECT_EQ(willow.height, 608);
  EXPECT_DOUBLE_EQ(willow.resolution, 0.10);
  const OccupancyGrid rilo = loadMap(test::robotMap("rilo"));  // free_thresh 0.25, mode trinary
  EXPECT_EQ(rilo.width, 1235);
  EXPECT_NEAR(rilo.origin.x, -42.5, 1e-12);
}

TEST(MapIo, RoundTripKeepsCellsAndOrigin) {
  OccupancyGrid g = loadMap(test::referenceMap("freiburg-079"));
  g.origin.yaw = 0.25;  // a rotated origin must survive too
  for (const char* ext : {".pgm", ".png"}) {
    const fs::path yaml = tempDir() / (std::string("roundtrip") + (ext[2] == 'g' ? "_pgm" : "_png") + ".yaml");
    saveMap(g, yaml.string(), ext);
    const OccupancyGrid back = loadMap(yaml.string());
    ASSERT_EQ(back.width, g.width);
    ASSERT_EQ(back.height, g.height);
    EXPECT_DOUBLE_EQ(back.resolution, g.resolution);
    EXPECT_DOUBLE_EQ(back.origin.x, g.origin.x);
    EXPECT_DOUBLE_EQ(back.origin.y, g.origin.y);
    EXPECT_DOUBLE_EQ(back.origin.yaw, g.origin.yaw);
    EXPECT_EQ(back.data, g.data) << ext;
  }
}

// The PGM is written a row at a time (a map is never held twice as an image): the file must be
// the one OpenCV wrote from the whole image, byte for byte, map_saver's trinary rule included.
TEST(MapIo, ThePgmWrittenRowByRowIsTheImageOpenCvWrites) {
  OccupancyGrid g;
  g.width = 7, g.height = 3, g.resolution = 0.05;
  g.data = {-1, 0, 25, 26, 64, 65, 100, 100, 65, 64, 26, 25, 0, -1, 0, 0, 100, -1, 50, 50, 0};
  for (const OccupancyGrid& grid : {g, loadMap(test::referenceMap("freiburg-079"))}) {
    cv::Mat image(grid.height, grid.width, CV_8U);
    for (int r = 0; r < grid.height; ++r)
      for (int c = 0; c < grid.width; ++c) {
        const int v = grid.at(c, r);
        image.at<uint8_t>(grid.height - 1 - r, c) = v < 0 ? 205 : (v >= 65 ? 0 : (v <= 25 ? 254 : 205));
      }
    std::vector<uchar> expected;
    ASSERT_TRUE(cv::imencode(".pgm", image, expected));
    const fs::path yaml = tempDir() / "rows.yaml";
    saveMap(grid, yaml.string(), ".pgm");
    std::ifstream in(tempDir() / "rows.pgm", std::ios::binary);
    const std::vector<uchar> written{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    EXPECT_EQ(written, expected) << grid.width << " x " << grid.height;
  }
}

TEST(MapIo, HonoursNegateScaleAndRawModes) {
  const fs::path dir = tempDir();
  cv::Mat image(1, 4, CV_8U);
  image.at<uint8_t>(0, 0) = 0, image.at<uint8_t>(0, 1) = 128, image.at<uint8_t>(0, 2) = 254, image.at<uint8_t>(0, 3) = 50;
  cv::imwrite((dir / "modes.pgm").string(), image);
  const std::string common = "image: modes.pgm\nresolution: 0.1\norigin: [1, 2, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  writeText(dir / "trinary.yaml", common + "negate: 0\n");
  writeText(dir / "negate.yaml", common + "negate: 1\n");
  writeText(dir / "scale.yaml", common + "negate: 0\nmode: scale\n");
  writeText(dir / "raw.yaml", common + "negate: 0\nmode: raw\n");
  EXPECT_EQ(loadMap((dir / "trinary.yaml").string()).data, (std::vector<int8_t>{100, -1, 0, 100}));
  // negate: p = v / 255, so 50 -> 0.196 is just above free_thresh: unknown.
  EXPECT_EQ(loadMap((dir / "negate.yaml").string()).data, (std::vector<int8_t>{0, -1, 100, -1}));
  // scale: p = (255 - 128) / 255 = 0.498 -> 99 * (0.498 - 0.196) / (0.65 - 0.196) = 66
  EXPECT_EQ(loadMap((dir / "scale.yaml").string()).data, (std::vector<int8_t>{100, 66, 0, 100}));
  EXPECT_EQ(loadMap((dir / "raw.yaml").string()).data, (std::vector<int8_t>{0, -1, -1, 50}));
}

std::string readAll(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A map saved over an older one is written whole or not at all: a write that fails midway
// (a full disk, a crash) leaves the older map as it was and no stray file beside it; a link is
// followed, a device written in place (never replaced by a file: the tests run as root).
TEST(MapIo, ASaveIsWholeOrNotAtAll) {
  const fs::path dir = tempDir() / "atomic";
  fs::create_directories(dir);
  const OccupancyGrid grid = loadMap(test::referenceMap("intel"));
  saveMap(grid, (dir / "map.yaml").string(), ".pgm");
  const std::string image = readAll(dir / "map.pgm"), yaml = readAll(dir / "map.yaml");
  ASSERT_GT(image.size(), 100000u);

  // A disk that fills up while the map is saved again (a file size limit stands in for it).
  OccupancyGrid other = grid;
  std::fill(other.data.begin(), other.data.end(), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit limit{}, small{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &limit), 0);
  small = limit;
  small.rlim_cur = 20000;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string error;
  try {
    saveMap(other, (dir / "map.yaml").string(), ".pgm");
  } catch (const MapIoError& e) {
    error = e.what();
  }
  ::setrlimit(RLIMIT_FSIZE, &limit);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_NE(error.find("map.pgm: write failed"), std::string::npos) << error;
  EXPECT_TRUE(readAll(dir / "map.pgm") == image) << "the older map's image was damaged";

  const auto half_then_crash = [](std::ostream& out) {
    out << std::string(50000, 'x');
    throw std::runtime_error("crashed midway");
  };
  EXPECT_THROW(writeFileAtomically((dir / "map.pgm").string(), half_then_crash), std::runtime_error);
  EXPECT_TRUE(readAll(dir / "map.pgm") == image) << "the older map's image was damaged";
  size_t files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 2u) << "a temporary file was left beside the map";
  EXPECT_EQ(loadMap((dir / "map.yaml").string()).data, grid.data);

  // A map saved again replaces both files whole, with the permissions a new file gets.
  const mode_t mask = ::umask(027);
  saveMap(grid, (dir / "map.yaml").string(), ".pgm");
  ::umask(mask);
  EXPECT_TRUE(readAll(dir / "map.pgm") == image) << "the same map saved again differs";
  EXPECT_TRUE(readAll(dir / "map.yaml") == yaml);
  EXPECT_EQ(fs::status(dir / "map.pgm").permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);

  // A link to a file elsewhere: the file it points to gets the content, the link stays.
  fs::create_directories(dir / "elsewhere");
  writeText(dir / "elsewhere" / "target.txt", "old");
  fs::create_symlink(dir / "elsewhere" / "target.txt", dir / "link.txt");
  writeFileAtomically((dir / "link.txt").string(), [](std::ostream& out) { out << "new"; });
  EXPECT_TRUE(fs::is_symlink(dir / "link.txt"));
  EXPECT_EQ(readAll(dir / "elsewhere" / "target.txt"), "new");

  // A device is written in place and stays a device.
  writeFileAtomically("/dev/null", [](std::ostream& out) { out << "nothing"; });
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
}

TEST(MapIo, BadFilesGiveErrorsNamingTheFile) {
  const fs::path dir = tempDir();
  cv::imwrite((dir / "ok.pgm").string(), cv::Mat(3, 3, CV_8U, cv::Scalar(254)));
  const std::string tail = "origin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  writeText(dir / "zero_res.yaml", "image: ok.pgm\nresolution: 0\n" + tail);
  writeText(dir / "nan_res.yaml", "image: ok.pgm\nresolution: .nan\n" + tail);
  writeText(dir / "no_image.yaml", "image: missing.pgm\nresolution: 0.05\n" + tail);
  writeText(dir / "malformed.yaml", "image: [ok.pgm\nresolution: : 0.05\n");
  writeText(dir / "bad_origin.yaml", "image: ok.pgm\nresolution: 0.05\norigin: [0, 0]\n");
  writeText(dir / "not_image.pgm", "P5\n100 100\n255\nshort");
  writeText(dir / "truncated.yaml", "image: not_image.pgm\nresolution: 0.05\n" + tail);
  EXPECT_NE(loadError(dir / "zero_res.yaml").find("resolution"), std::string::npos);
  EXPECT_NE(loadError(dir / "nan_res.yaml").find("resolution"), std::string::npos);
  EXPECT_NE(loadError(dir / "no_image.yaml").find("missing.pgm"), std::string::npos);
  EXPECT_NE(loadError(dir / "malformed.yaml").find("malformed yaml"), std::string::npos);
  EXPECT_NE(loadError(dir / "bad_origin.yaml").find("origin"), std::string::npos);
  EXPECT_NE(loadError(dir / "truncated.yaml").find("not_image.pgm"), std::string::npos);
  EXPECT_NE(loadError(dir / "nothing_here.yaml").find("nothing_here.yaml: no such file"), std::string::npos);
  // An image name longer than the system allows (found by fuzz_map_loader: it aborted the loader).
  writeText(dir / "long_name.yaml", "image: " + std::string(5000, 'x') + ".pgm\nresolution: 0.05\n" + tail);
  EXPECT_NE(loadError(dir / "long_name.yaml").find("cannot be looked up"), std::string::npos);
  EXPECT_NE(loadError(dir / std::string(5000, 'y')).find("cannot be looked up"), std::string::npos);
  // A bitmap (P4) taller than OpenCV reads: OpenCV threw and aborted the loader (found by
  // fuzz_map_loader). Its header is checked like a PGM's, and what OpenCV still refuses (a
  // full-size file 5 x 1 100 000) is refused by name, never thrown through.
  writeText(dir / "tall.pbm", "P4\n5 4000000\n" + std::string(16, '\0'));
  writeText(dir / "tall.yaml", "image: tall.pbm\nresolution: 0.05\n" + tail);
  EXPECT_NE(loadError(dir / "tall.yaml").find("tall.pbm: image data truncated"), std::string::npos);
  writeText(dir / "tall_full.pbm", "P4\n5 1100000\n" + std::string(1100000, '\0'));
  writeText(dir / "tall_full.yaml", "image: tall_full.pbm\nresolution: 0.05\n" + tail);
  EXPECT_NE(loadError(dir / "tall_full.yaml").find("tall_full.pbm: unreadable image: OpenCV refuses it"), std::string::npos);
}

TEST(Grid, ValidateRejectsMalformedGrids) {
  OccupancyGrid g;
  g.width = 4, g.height = 3, g.resolution = 0.05, g.data.assign(12, 0);
  EXPECT_EQ(validateGrid(g), "");
  g.data.resize(11);
  EXPECT_NE(validateGrid(g).find("data has 11 cells"), std::string::npos);
  g.data.assign(12, 0);
  g.resolution = std::nan("");
  EXPECT_NE(validateGrid(g).find("resolution"), std::string::npos);
  g.resolution = 0.05;
  g.data[3] = 101;
  EXPECT_NE(validateGrid(g).find("outside -1..100"), std::string::npos);
  g.data[3] = 0;
  EXPECT_NE(validateGrid(g, 10).find("exceeds"), std::string::npos);
}

TEST(Pose2D, ComposeAndInverse) {
  const Pose2D a{1.0, 2.0, 0.7}, b{-3.0, 0.5, -2.0};
  const Pose2D id = a.compose(a.inverse());
  EXPECT_NEAR(id.x, 0, 1e-12);
  EXPECT_NEAR(id.y, 0, 1e-12);
  EXPECT_NEAR(id.yaw, 0, 1e-12);
  double x, y, x2, y2;
  a.compose(b).apply(0.3, -0.2, x, y);
  b.apply(0.3, -0.2, x2, y2);
  a.apply(x2, y2, x2, y2);
  EXPECT_NEAR(x, x2, 1e-12);
  EXPECT_NEAR(y, y2, 1e-12);
}
