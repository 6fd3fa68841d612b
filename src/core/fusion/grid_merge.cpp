#include "mrslam/fusion/grid_merge.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace mrslam::fusion {

namespace {

// Output rows summed at a time: the float sums of a whole large map would hold 5 bytes a cell
// at once (MIT's infinite corridor, 5357 x 5096 cells: 136 MB beside the 27 MB result).
constexpr int kBandRows = 256;

const OccupancyGrid& geometryOf(const PlacedGrid& p) { return p.grid ? *p.grid : p.packed->geometry(); }

// One input grid and where it lands in the output: its cells are read through an affine map
// from output cell centres (the output's grid frame, metres) to its own cell coordinates.
struct Footprint {
  const PlacedGrid* piece = nullptr;
  const OccupancyGrid* grid = nullptr;  // the cells; a packed piece's only while they are read
  OccupancyGrid unpacked;
  double c = 0, s = 0, tx = 0, ty = 0;
  int col0 = 0, col1 = -1, row0 = 0, row1 = -1;  // output cells under its bounding box

  void load() {
    if (grid) return;
    unpacked = piece->packed->unpack();
    grid = &unpacked;
  }
  void drop() {
    if (!piece->packed) return;
    unpacked = OccupancyGrid{};
    grid = nullptr;
  }
};

Footprint footprintOf(const PlacedGrid& p, const OccupancyGrid& out) {
  const OccupancyGrid& g = geometryOf(p);
  Footprint f;
  f.piece = &p;
  f.grid = p.grid;
  const Pose2D out_to_g = g.origin.inverse().compose(p.pose.inverse()).compose(out.origin);
  f.c = std::cos(out_to_g.yaw) / g.resolution, f.s = std::sin(out_to_g.yaw) / g.resolution;
  f.tx = out_to_g.x / g.resolution, f.ty = out_to_g.y / g.resolution;
  int col0 = out.width, col1 = -1, row0 = out.height, row1 = -1;
  const double w = g.width * g.resolution, h = g.height * g.resolution, res = out.resolution;
  for (const auto& [gx, gy] : {std::pair{0.0, 0.0}, {w, 0.0}, {0.0, h}, {w, h}}) {
    double x, y;  // the corner in out's grid frame (metres)
    out.origin.inverse().compose(p.pose).compose(g.origin).apply(gx, gy, x, y);
    col0 = std::min(col0, static_cast<int>(std::floor(x / res)) - 1), col1 = std::max(col1, static_cast<int>(std::ceil(x / res)) + 1);
    row0 = std::min(row0, static_cast<int>(std::floor(y / res)) - 1), row1 = std::max(row1, static_cast<int>(std::ceil(y / res)) + 1);
  }
  f.col0 = std::max(col0, 0), f.row0 = std::max(row0, 0);
  f.col1 = std::min(col1, out.width - 1), f.row1 = std::min(row1, out.height - 1);
  return f;
}

// Adds the grid's known cells under output rows [band0, band1) to the band's sums.
void accumulate(const Footprint& f, const OccupancyGrid& out, int band0, int band1, const float* lut,
                std::vector<float>& log_odds, std::vector<uint8_t>& known) {
  const OccupancyGrid& g = *f.grid;
  const double res = out.resolution;
  for (int r = std::max(f.row0, band0); r <= std::min(f.row1, band1 - 1); ++r) {
    const double y = (r + 0.5) * res;
    for (int col = f.col0; col <= f.col1; ++col) {
      const double x = (col + 0.5) * res;
      const double gx = f.c * x - f.s * y + f.tx, gy = f.s * x + f.c * y + f.ty;
      if (gx < 0 || gy < 0 || gx >= g.width || gy >= g.height) continue;
      const int v = g.at(static_cast<int>(gx), static_cast<int>(gy));
      if (v < 0) continue;
      const size_t i = static_cast<size_t>(r - band0) * out.width + col;
      log_odds[i] += lut[v];
      known[i] = 1;
    }
  }
}

}  // namespace

OccupancyGrid mergeGrids(const OccupancyGrid& reference, const std::vector<PlacedGrid>& others) {
  std::vector<PlacedGrid> all{{&reference, Pose2D{}}};
  all.insert(all.end(), others.begin(), others.end());
  return mergeGrids(all);
}

OccupancyGrid mergeGrids(const std::vector<PlacedGrid>& all) {
  OccupancyGrid out = mergedExtent(all);
  out.data.resize(static_cast<size_t>(out.width) * out.height);
  mergeRowsInto(all, out, std::vector<uint8_t>(static_cast<size_t>(out.height), 1));
  return out;
}

OccupancyGrid mergedExtent(const std::vector<PlacedGrid>& all) {
  if (all.empty()) return OccupancyGrid{};
  const OccupancyGrid& reference = geometryOf(all.front());

  // Bounding box of every grid's corners in the reference grid frame (metres).
  const Pose2D to_ref_grid = reference.origin.inverse();
  double min_x = std::numeric_limits<double>::max(), min_y = min_x, max_x = -min_x, max_y = -min_x;
  for (const PlacedGrid& p : all) {
    const OccupancyGrid& g = geometryOf(p);
    const Pose2D grid_in_ref = to_ref_grid.compose(p.pose).compose(g.origin);
    const double w = g.width * g.resolution, h = g.height * g.resolution;
    for (const auto& [cx, cy] : {std::pair{0.0, 0.0}, {w, 0.0}, {0.0, h}, {w, h}}) {
      double x, y;
      grid_in_ref.apply(cx, cy, x, y);
      min_x = std::min(min_x, x), max_x = std::max(max_x, x);
      min_y = std::min(min_y, y), max_y = std::max(max_y, y);
    }
  }
  const double res = reference.resolution;
  // Keep the reference's cell lattice: shift the bounds to whole cells.
  const int c0 = static_cast<int>(std::floor(min_x / res)), r0 = static_cast<int>(std::floor(min_y / res));
  OccupancyGrid out;
  out.resolution = res;
  out.width = static_cast<int>(std::ceil(max_x / res)) - c0;
  out.height = static_cast<int>(std::ceil(max_y / res)) - r0;
  out.origin = reference.origin.compose(Pose2D{c0 * res, r0 * res, 0.0});
  return out;
}

std::pair<int, int> rowsReached(const PlacedGrid& piece, const OccupancyGrid& extent) {
  const Footprint f = footprintOf(piece, extent);
  if (f.col1 < f.col0) return {0, -1};
  return {f.row0, f.row1};
}

int mergeRowsInto(const std::vector<PlacedGrid>& all, OccupancyGrid& out, const std::vector<uint8_t>& redo) {
  if (redo.size() != static_cast<size_t>(std::max(out.height, 0)) ||
      out.data.size() != static_cast<size_t>(std::max(out.width, 0)) * redo.size())
    throw std::invalid_argument("mergeRowsInto: one flag a row and the cells of the extent are needed");
  float lut[101];
  for (int v = 0; v <= 100; ++v) {
    const double p = std::clamp(v / 100.0, 0.02, 0.98);
    lut[v] = static_cast<float>(std::log(p / (1.0 - p)));
  }
  std::vector<Footprint> footprints;
  for (const PlacedGrid& p : all) footprints.push_back(footprintOf(p, out));
  const size_t band_cells = static_cast<size_t>(out.width) * std::min(kBandRows, out.height);
  std::vector<float> log_odds(band_cells);
  std::vector<uint8_t> known(band_cells);
  int merged = 0;
  // Bands of up to kBandRows flagged rows in a row, bottom to top (all rows flagged: the bands
  // of a whole merge).
  for (int band0 = 0, band1 = 0; band0 < out.height; band0 = band1) {
    band1 = band0 + 1;
    if (!redo[static_cast<size_t>(band0)]) continue;
    while (band1 < out.height && band1 - band0 < kBandRows && redo[static_cast<size_t>(band1)]) ++band1;
    merged += band1 - band0;
    std::fill(log_odds.begin(), log_odds.end(), 0.0f);
    std::fill(known.begin(), known.end(), uint8_t{0});
    for (Footprint& f : footprints) {
      if (f.row1 < band0) f.drop();  // past its last band (bands skipped since may have held it)
      if (f.row1 < band0 || f.row0 >= band1 || f.col1 < f.col0) continue;
      f.load();
      accumulate(f, out, band0, band1, lut, log_odds, known);
      if (f.row1 < band1) f.drop();  // its last band
    }
    int8_t* cells = out.data.data() + static_cast<size_t>(band0) * out.width;
    for (size_t i = 0; i < static_cast<size_t>(band1 - band0) * out.width; ++i)
      cells[i] = known[i] ? static_cast<int8_t>(std::lround(100.0 / (1.0 + std::exp(-log_odds[i]))))
                          : OccupancyGrid::kUnknown;
  }
  return merged;
}

}  // namespace mrslam::fusion
