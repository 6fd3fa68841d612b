// mrslam::SharedMap: the C++ face of mrslam/LocalMapShare that carries the grid by pointer.
//
// Its ROS traits (MD5, type, definition) are those of LocalMapShare and its serializer writes
// the same bytes, so it interoperates with any LocalMapShare publisher or subscriber in other
// processes, while nodelets in one manager pass it, and the grid inside it, without a copy:
// the map-share nodelet puts the very OccupancyGrid object published by the mapping nodelet
// into the message. Like every published message, it must never be modified after publishing.
#pragma once

#include <boost/make_shared.hpp>
#include <geometry_msgs/PoseWithCovariance.h>
#include <mrslam/LocalMapShare.h>
#include <nav_msgs/OccupancyGrid.h>
#include <ros/message_traits.h>
#include <ros/serialization.h>
#include <std_msgs/Header.h>

#include <cstring>
#include <string>

#include "mrslam/ros/wire_traits.h"

namespace mrslam {

struct SharedMap {
  std_msgs::Header header;
  std::string robot_id;
  nav_msgs::OccupancyGridConstPtr map;  // never null once published
  geometry_msgs::PoseWithCovariance pose;
  uint32_t version = 0;

  using Ptr = boost::shared_ptr<SharedMap>;
  using ConstPtr = boost::shared_ptr<const SharedMap>;
};

}  // namespace mrslam

namespace ros {
namespace message_traits {

template <>
struct MD5Sum<mrslam::SharedMap> : SameMD5<mrslam::SharedMap, mrslam::LocalMapShare> {};
template <>
struct DataType<mrslam::SharedMap> : SameDataType<mrslam::SharedMap, mrslam::LocalMapShare> {};
template <>
struct Definition<mrslam::SharedMap> : SameDefinition<mrslam::SharedMap, mrslam::LocalMapShare> {};

}  // namespace message_traits

namespace serialization {

template <>
struct Serializer<mrslam::SharedMap> {
  template <typename Stream>
  static void write(Stream& stream, const mrslam::SharedMap& m) {
    stream.next(m.header);
    stream.next(m.robot_id);
    stream.next(m.map ? *m.map : nav_msgs::OccupancyGrid());
    stream.next(m.pose);
    stream.next(m.version);
  }
  template <typename Stream>
  static void read(Stream& stream, mrslam::SharedMap& m) {
    stream.next(m.header);
    stream.next(m.robot_id);
    auto grid = boost::make_shared<nav_msgs::OccupancyGrid>();
    stream.next(grid->header);
    stream.next(grid->info);
    // roscpp's vector reader resizes to the length the message claims before checking that the
    // message holds it: a peer claiming 4 GB of cells would have them allocated. Checked first.
    uint32_t cells = 0;
    stream.next(cells);
    if (cells > stream.getLength())
      throw ros::serialization::StreamOverrunException("LocalMapShare claims " + std::to_string(cells) +
                                                       " cells, the message holds " + std::to_string(stream.getLength()) + " bytes");
    grid->data.resize(cells);
    if (cells) std::memcpy(grid->data.data(), stream.advance(cells), cells);
    m.map = grid;
    stream.next(m.pose);
    stream.next(m.version);
  }
  static uint32_t serializedLength(const mrslam::SharedMap& m) {
    return serializationLength(m.header) + serializationLength(m.robot_id) +
           serializationLength(m.map ? *m.map : nav_msgs::OccupancyGrid()) + serializationLength(m.pose) +
           serializationLength(m.version);
  }
};

}  // namespace serialization
}  // namespace ros
