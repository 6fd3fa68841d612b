// A merger's record of what lay behind each estimate, so that any merge a robot made or refused
// can be replayed offline, exactly: the two maps as they were aligned, and one line per estimate.
// The fusion reads nothing of a map but its structure and its cells' trinary classes
// (toTernary: map_saver's rule), which a map_server file keeps, so the replay
//
//   mrslam_merge [--held X,Y,YAW] DIR/PEER/latest_a.yaml DIR/PEER/latest_b.yaml
//
// gives the estimate the merger got. Files under DIR/PEER for the peer's own estimates, and
// under DIR/PEER/via_VIA for its relays through VIA (a subfolder: every id is a plain name, so a
// relay's folder cannot be another peer's, as "<peer>_via_<via>" could with ids holding "_via_"):
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

// Writes the record of one estimate of the peer's map B in A (A: our map, or for a relay the map
// of `via`; `via` empty for a direct estimate; `held`: the pose passed to alignMaps). Throws
// MapIoError or std::invalid_argument (an id that is not [A-Za-z0-9_]+) naming the problem.
void recordEstimate(const std::string& dir, const std::string& peer, const std::string& via, const OccupancyGrid& a,
                    const OccupancyGrid& b, const std::optional<Pose2D>& held, const FusionResult& result,
                    double wall_s);

}  // namespace mrslam::fusion
