// libFuzzer target: a LocalMapShare as it arrives from the network, deserialised into
// mrslam::SharedMap and put through every check the map-merge nodelet makes before a peer's
// map reaches the fusion; the same bytes also as a CompressedMapShare, inflated as the nodelet
// does. Contract: a refusal with a reason or a grid the fusion accepts as input
// (fusion::peerMapProblem empty), never a crash, never more cells than the header claims.
#include <cstdint>

#include "mrslam/fusion/map_fusion.h"
#include "mrslam/fusion/peer_registry.h"
#include "mrslam/ros/compressed_share.h"
#include "mrslam/ros/shared_map.h"
#include "ros_conversions.h"
#include "share_codec.h"

namespace {
void inflateCompressed(const uint8_t* data, size_t size) {
  mrslam::ReceivedCompressedShare received;  // the type the merge nodelet subscribes with
  try {
    ros::serialization::IStream stream(const_cast<uint8_t*>(data), static_cast<uint32_t>(size));
    ros::serialization::deserialize(stream, received);
  } catch (const ros::Exception&) {
    return;
  }
  const mrslam::CompressedMapShare& msg = received.msg;
  nav_msgs::OccupancyGrid grid;
  if (mrslam::nodelets::inflateGrid(msg, 4'000'000, grid).empty() &&
      grid.data.size() != static_cast<size_t>(msg.info.width) * msg.info.height)
    __builtin_trap();  // inflated to another size than the header claims
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  inflateCompressed(data, size);
  mrslam::SharedMap share;
  try {
    ros::serialization::IStream stream(const_cast<uint8_t*>(data), static_cast<uint32_t>(size));
    ros::serialization::deserialize(stream, share);
  } catch (const ros::Exception&) {
    return 0;  // too short: refused by roscpp before any callback
  }
  if (!mrslam::fusion::isValidRobotId(share.robot_id) || !share.map) return 0;
  if (!mrslam::nodelets::gridMsgProblem(*share.map, 4'000'000).empty()) return 0;
  const mrslam::OccupancyGrid grid = mrslam::nodelets::gridFromMsg(*share.map);
  const mrslam::fusion::FusionParams params;
  if (mrslam::fusion::peerMapProblem(grid, 0.05, params).empty() && !mrslam::validateGrid(grid).empty())
    __builtin_trap();  // the fusion would have been handed a grid it cannot take
  (void)mrslam::fusion::summarize(grid);
  return 0;
}
