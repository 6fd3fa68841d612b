// mrslam::ReceivedCompressedShare: mrslam/CompressedMapShare as a subscriber receives it. Same
// wire format and ROS traits; only its reader differs: roscpp's generated reader resizes the
// `cells` array to whatever length the message claims before checking that the message holds
// it, so one hostile message could have 4 GB allocated. This reader checks first (as
// SharedMap does for LocalMapShare's grid).
#pragma once

#include <mrslam/CompressedMapShare.h>
#include <ros/message_traits.h>
#include <ros/serialization.h>

#include <cstring>
#include <string>

#include "mrslam/ros/wire_traits.h"

namespace mrslam {

struct ReceivedCompressedShare {
  CompressedMapShare msg;

  using Ptr = boost::shared_ptr<ReceivedCompressedShare>;
  using ConstPtr = boost::shared_ptr<const ReceivedCompressedShare>;
};

}  // namespace mrslam

namespace ros {
namespace message_traits {

template <>
struct MD5Sum<mrslam::ReceivedCompressedShare> : SameMD5<mrslam::ReceivedCompressedShare, mrslam::CompressedMapShare> {};
template <>
struct DataType<mrslam::ReceivedCompressedShare> : SameDataType<mrslam::ReceivedCompressedShare, mrslam::CompressedMapShare> {};
template <>
struct Definition<mrslam::ReceivedCompressedShare> : SameDefinition<mrslam::ReceivedCompressedShare, mrslam::CompressedMapShare> {};

}  // namespace message_traits

namespace serialization {

template <>
struct Serializer<mrslam::ReceivedCompressedShare> {
  template <typename Stream>
  static void write(Stream& stream, const mrslam::ReceivedCompressedShare& m) {
    stream.next(m.msg);
  }
  template <typename Stream>
  static void read(Stream& stream, mrslam::ReceivedCompressedShare& m) {
    mrslam::CompressedMapShare& msg = m.msg;
    stream.next(msg.header);
    stream.next(msg.robot_id);
    stream.next(msg.map_header);
    stream.next(msg.info);
    stream.next(msg.encoding);
    uint32_t bytes = 0;
    stream.next(bytes);
    if (bytes > stream.getLength())
      throw StreamOverrunException("CompressedMapShare claims " + std::to_string(bytes) +
                                   " bytes of cells, the message holds " + std::to_string(stream.getLength()));
    msg.cells.resize(bytes);
    if (bytes) std::memcpy(msg.cells.data(), stream.advance(bytes), bytes);
    stream.next(msg.pose);
    stream.next(msg.version);
  }
  static uint32_t serializedLength(const mrslam::ReceivedCompressedShare& m) { return serializationLength(m.msg); }
};

}  // namespace serialization
}  // namespace ros
