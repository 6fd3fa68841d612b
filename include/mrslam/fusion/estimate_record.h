// A merger's record of what lay behind each estimate, so that any merge a robot made or refused
// can be replayed offline, exactly: the two maps as they were aligned, and one line per estimate.
// The fusion reads nothing of a map but its structure and its cells' trinary classes
// (toTernary: map_saver's rule), which a map_server file keeps, so the replay
//
//   mrslam_merge [--held X,Y,YAW] DIR/NAME/latest_a.yaml DIR/NAME/latest_b.yaml
//
// gives the estimate the merger got. Files under DIR/NAME (NAME: the peer's id, or
// "<peer>_via_<via>" for a relay):
//   latest_a.yaml, latest_b.yaml      A (our map, or the via's) and B (the peer's) of the newest estimate
//   accepted_a.yaml, accepted_b.yaml  the same for the newest accepted estimate
//   estimates.tsv                     one line per estimate (columns in kEstimateRecordHeader)
#pragma once

#include <optional>
#include <string>

#include "mrslam/fusion/map_fusion.h"

namespace mrslam::fusion {

constexpr const char* kEstimateRecordHeader =
    "wall_s\taccepted\tx\ty\tyaw\tV\tshared_wall_m\theld\treason\n";

// A pose as estimates.tsv and the tools write it, "X,Y,YAW" (m, m, rad, to the bit), and back:
// nothing when the text is not three finite numbers and nothing else.
std::string poseText(const Pose2D& pose);
std::optional<Pose2D> parsePoseText(const std::string& text);

// Writes the record of one estimate of B in A (`held`: the pose passed to alignMaps). Throws
// MapIoError or std::invalid_argument (a NAME that is not [A-Za-z0-9_]+) naming the problem.
void recordEstimate(const std::string& dir, const std::string& name, const OccupancyGrid& a,
                    const OccupancyGrid& b, const std::optional<Pose2D>& held, const FusionResult& result,
                    double wall_s);

}  // namespace mrslam::fusion
