// ROS message traits for a C++ type that travels as an existing message (same MD5, type and
// definition) but is read or held differently: mrslam::SharedMap (LocalMapShare carrying its
// grid by pointer) and mrslam::ReceivedCompressedShare (CompressedMapShare read safely).
//   template <> struct MD5Sum<Custom> : SameMD5<Custom, Message> {};   (and DataType, Definition)
#pragma once

#include <ros/message_traits.h>

namespace ros {
namespace message_traits {

template <class Custom, class Message>
struct SameMD5 {
  static const char* value() { return MD5Sum<Message>::value(); }
  static const char* value(const Custom&) { return value(); }
};
template <class Custom, class Message>
struct SameDataType {
  static const char* value() { return DataType<Message>::value(); }
  static const char* value(const Custom&) { return value(); }
};
template <class Custom, class Message>
struct SameDefinition {
  static const char* value() { return Definition<Message>::value(); }
  static const char* value(const Custom&) { return value(); }
};

}  // namespace message_traits
}  // namespace ros
