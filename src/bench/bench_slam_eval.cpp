// mrslam_bench_slam_eval [--scan-relations N] [--wall-directions] [--split-global] LOG [LABEL=TRAJECTORY ...]: accuracy of
// trajectories against the reference poses of a corrected CARMEN log (Kümmerle et al. 2009
// relations), beside the raw wheel odometry chained from the log's ODOM lines. Prints markdown
// table rows:
//   | log | method | 1-step m | 1-step deg | 10-step m | 10-step deg | global m | global deg | conflict % |
// With --scan-relations N, two more columns: the error against up to N relations between scans
// of different passes that the scans themselves fix (bench/scan_relations.h), and a row for the
// reference poses against them; the relations' count goes to stderr. With --wall-directions,
// one more: how far the wall directions of the map's regions spread (bench/wall_directions.h:
// a bent map spreads, whatever its revisits say): standard deviation and range in degrees, and
// the number of regions with walls enough to count. With --split-global, two more: the global
// error with the reference's positions and the trajectory's own headings, and with its own
// positions and the reference's headings (bench/trajectory_metrics.h, splitGlobalError): which
// of the two makes a global error.
// Trajectory lines are matched to the log's scans by scan index where they carry one, else by
// time stamp, in order.
//
// Conflict: how much the scans cast along the trajectory contradict each other (bench/
// map_consistency.h: the share of laser hits in cells that other rays pass through more often).
// It needs no reference: a row for the reference poses themselves shows where the reference
// stands (the reference poses carry errors of their own).
#include <algorithm>
#include <cstdlib>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <string>

#include "mrslam/bench/map_consistency.h"
#include "mrslam/bench/scan_relations.h"
#include "mrslam/bench/trajectory_metrics.h"
#include "mrslam/bench/wall_directions.h"
#include "mrslam/slam/robot_log.h"

namespace {

using mrslam::Pose2D;
namespace bench = mrslam::bench;

std::string cell(double mean, double std, double scale, int precision) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f ± %.*f", precision, mean * scale, precision, std * scale);
  return buffer;
}

// The scans' conflict (percent) when cast along `poses` (scans[i] at poses[i]).
double conflictPercent(const mrslam::slam::RobotLog& log, const std::vector<size_t>& scans, const std::vector<Pose2D>& poses) {
  std::vector<const mrslam::slam::LaserScan*> taken;
  for (size_t k : scans) taken.push_back(&log.records[k].scan);
  return 100.0 * bench::mapConsistency(taken, poses, log.laser_in_base).conflict;
}

// The relations between scans of `trajectory_scans` (log indices, in trajectory order),
// re-indexed into the trajectory; relations with a scan the trajectory lacks are left out.
std::vector<bench::Relation> relationsWithin(const std::vector<bench::Relation>& relations, const std::vector<size_t>& trajectory_scans) {
  std::vector<long> position;
  for (size_t k = 0; k < trajectory_scans.size(); ++k) {
    if (trajectory_scans[k] >= position.size()) position.resize(trajectory_scans[k] + 1, -1);
    position[trajectory_scans[k]] = static_cast<long>(k);
  }
  std::vector<bench::Relation> within;
  for (const bench::Relation& r : relations)
    if (r.i < position.size() && r.j < position.size() && position[r.i] >= 0 && position[r.j] >= 0)
      within.push_back({static_cast<size_t>(position[r.i]), static_cast<size_t>(position[r.j]), r.motion});
  return within;
}

std::string scanCheckedColumns(const std::vector<Pose2D>& estimate, const std::vector<bench::Relation>& relations) {
  const auto e = bench::relationError(estimate, relations);
  if (e.count == 0) return " – | – |";
  return " " + cell(e.trans_mean, e.trans_std, 1, 3) + " | " + cell(e.rot_mean, e.rot_std, 180.0 / M_PI, 2) + " |";
}

// The spread of the regions' wall directions (degrees, standard deviation and largest minus
// smallest) of the map the scans make along `poses` (bench/wall_directions.h).
std::string wallDirectionsColumn(const mrslam::slam::RobotLog& log, const std::vector<size_t>& scans,
                                 const std::vector<Pose2D>& poses) {
  std::vector<const mrslam::slam::LaserScan*> taken;
  for (size_t k : scans) taken.push_back(&log.records[k].scan);
  const auto walls = bench::wallDirections(taken, poses, log.laser_in_base);
  if (walls.region_deg.size() < 2) return " – |";  // too few walls anywhere to compare regions
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), " %.2f (%.2f, %zu) |", walls.std_deg, walls.spread_deg, walls.region_deg.size());
  return buffer;
}

// The global error (the table's 500 pairs) with the reference's positions and `poses`' own
// headings, then with `poses`' own positions and the reference's headings.
std::string splitGlobalColumns(const std::vector<Pose2D>& poses, const std::vector<size_t>& scans,
                               const std::vector<Pose2D>& reference) {
  std::vector<Pose2D> matched;
  for (size_t k : scans) matched.push_back(reference[k]);
  if (matched.size() < 2) return " – | – |";
  const auto split = bench::splitGlobalError(poses, matched, bench::randomPairs(matched.size(), 500, 2009));
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), " %.2f | %.2f |", split.own_headings, split.own_positions);
  return buffer;
}

void row(const std::string& log_name, const std::string& label, const std::vector<Pose2D>& estimate,
         const std::vector<Pose2D>& reference, double conflict, const std::string& more_columns) {
  const double deg = 180.0 / M_PI;
  const auto one = bench::relationError(estimate, reference, bench::consecutivePairs(reference.size(), 1));
  const auto ten = bench::relationError(estimate, reference, bench::consecutivePairs(reference.size(), 10));
  const auto global = bench::relationError(estimate, reference, bench::randomPairs(reference.size(), 500, 2009));
  std::cout << "| " << log_name << " | " << label << " | " << cell(one.trans_mean, one.trans_std, 1, 3) << " | "
            << cell(one.rot_mean, one.rot_std, deg, 2) << " | " << cell(ten.trans_mean, ten.trans_std, 1, 3) << " | "
            << cell(ten.rot_mean, ten.rot_std, deg, 2) << " | " << cell(global.trans_mean, global.trans_std, 1, 2)
            << " | " << cell(global.rot_mean, global.rot_std, deg, 1) << " | " << std::fixed << std::setprecision(2) << conflict
            << " |" << more_columns << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  int first = 1;
  size_t relation_count = 0;
  bool bad_usage = false, wall_directions = false, split_global = false;
  while (first < argc && std::string(argv[first]).rfind("--", 0) == 0 && !bad_usage) {
    const std::string flag = argv[first];
    if (flag == "--scan-relations") {
      char* end = nullptr;
      relation_count = first + 1 < argc ? std::strtoul(argv[first + 1], &end, 10) : 0;
      bad_usage = first + 1 >= argc || *end != '\0' || relation_count < 1 || relation_count > 100000;
      first += 2;
    } else if (flag == "--wall-directions") {
      wall_directions = true;
      ++first;
    } else if (flag == "--split-global") {
      split_global = true;
      ++first;
    } else {
      bad_usage = true;  // an unknown flag
    }
  }
  if (argc <= first || bad_usage) {
    std::cerr << "usage: mrslam_bench_slam_eval [--scan-relations N (1..100000)] [--wall-directions] [--split-global] LOG "
                 "[LABEL=TRAJECTORY ...]\n";
    return 2;
  }
  try {
    const auto log = mrslam::slam::readRobotLog(argv[first]);
    if (!log.records.front().has_reference) throw std::runtime_error(std::string(argv[first]) + ": no reference poses");
    std::string name = argv[first];
    name = name.substr(name.find_last_of('/') + 1);
    name = name.substr(0, name.find('.'));
    std::vector<Pose2D> reference;
    for (const auto& r : log.records) reference.push_back(r.reference);
    std::vector<size_t> all(log.records.size());
    for (size_t k = 0; k < all.size(); ++k) all[k] = k;
    std::vector<bench::Relation> relations;
    if (relation_count > 0) {
      const auto checked = bench::scanCheckedRelations(log, relation_count, 2009);
      relations = checked.relations;
      std::cerr << name << ": " << relations.size() << " relations checked by the scans (" << checked.tried << " pairs tried of "
                << checked.candidates << " on different passes)\n";
    }
    auto more = [&](const std::vector<Pose2D>& poses, const std::vector<size_t>& scans) {
      std::string columns = relation_count > 0 ? scanCheckedColumns(poses, relationsWithin(relations, scans)) : "";
      if (wall_directions) columns += wallDirectionsColumn(log, scans, poses);
      if (split_global) columns += splitGlobalColumns(poses, scans, reference);
      return columns;
    };
    std::cout << "| " << name << " | reference poses (the truth used here) | – | – | – | – | – | – | " << std::fixed
              << std::setprecision(2) << conflictPercent(log, all, reference) << " |" << more(reference, all) << "\n";
    const auto odometry = mrslam::slam::chainOdometry(log);
    row(name, "odometry (raw, ODOM lines)", odometry, reference, conflictPercent(log, all, odometry), more(odometry, all));
    for (int i = first + 1; i < argc; ++i) {
      const std::string arg = argv[i];
      const size_t eq = arg.find('=');
      if (eq == std::string::npos) throw std::runtime_error("expected LABEL=TRAJECTORY, got " + arg);
      const auto trajectory = bench::readIndexedTrajectory(arg.substr(eq + 1));
      // Match by scan index when the trajectory has one (time stamps need not be unique), else
      // by time stamp, in order: scans the run did not use drop out of both sides.
      std::vector<Pose2D> estimate, matched_reference;
      std::vector<size_t> scans;
      size_t k = 0;
      for (const bench::TrajectoryEntry& e : trajectory) {
        if (e.scan >= 0) {
          if (static_cast<size_t>(e.scan) >= log.records.size()) throw std::runtime_error(arg + ": scan " + std::to_string(e.scan) + " not in the log");
          k = static_cast<size_t>(e.scan);
        } else {
          while (k < log.records.size() && log.records[k].scan.stamp != e.stamp) ++k;
          if (k == log.records.size()) throw std::runtime_error(arg + ": time stamp " + std::to_string(e.stamp) + " not in the log (or out of order)");
        }
        estimate.push_back(e.pose);
        scans.push_back(k);
        matched_reference.push_back(reference[k++]);
      }
      if (estimate.size() < log.records.size())
        std::cerr << arg << ": " << log.records.size() - estimate.size() << " scans not in the trajectory\n";
      row(name, arg.substr(0, eq), estimate, matched_reference, conflictPercent(log, scans, estimate), more(estimate, scans));
    }
  } catch (const std::exception& e) {
    std::cerr << "mrslam_bench_slam_eval: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
