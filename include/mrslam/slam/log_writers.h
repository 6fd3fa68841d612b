// Writing robot logs, for benchmarks that feed other tools the very data mrslam reads:
//   - fromScan(): the log from scan `first` on, as if the robot had started there (one run of
//     a whole log is one draw as well: which scan the map frame is anchored to and which scans
//     the loop closures meet decide a little of the result);
//   - decimate(): the same log at a slower scan rate (every k-th scan from scan `phase` on:
//     k phases give k different slow logs of one run), the odometry of the dropped scans
//     chained into the next kept one, so the raw odometry's error is that of the
//     full log (the corrected CARMEN logs re-anchor odometry at every scan: dropping lines
//     would lose motion);
//   - writeCarmenLog(): a CARMEN text log whose ODOM lines give exactly the records' odometry
//     (one anchor line with ipc time stamp 0 after each FLASER, as in the corrected logs, and one
//     line before the next FLASER), FLASER lines carrying the reference pose where known;
//   - writeMrptRawlog(): an MRPT rawlog (actions + sensory frames) with the same scans (beam
//     layout as mrslam reads it) and odometry, for MRPT's icp-slam and rbpf-slam.
// Each throws LogError naming the file when it cannot be written completely.
#pragma once

#include <string>

#include "mrslam/slam/robot_log.h"

namespace mrslam::slam {

RobotLog fromScan(const RobotLog& log, size_t first);
RobotLog decimate(const RobotLog& log, int every, int phase = 0);
void writeCarmenLog(const RobotLog& log, const std::string& path);
void writeMrptRawlog(const RobotLog& log, const std::string& path);

}  // namespace mrslam::slam
