// Parameters of a nodelet's private namespace, read from the master in one call, and the
// front end's parameters (config/robot.yaml) by the names the offline loader uses.
//
// One call, not one per key: on a robot whose link to the master is a lossy Wi-Fi hop
// (scripts/multi_host, 100 ms, 5 % loss), a round trip per key made the SLAM nodelet's
// start-up take 45 s. Lookups follow roscpp's NodeHandle::param: a missing key or a value of
// another type keeps the fallback; an integer is accepted where a double is wanted.
#pragma once

#include <ros/node_handle.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <cmath>
#include <limits>
#include <string>
#include <variant>

#include "mrslam/slam/robot_params.h"

namespace mrslam::nodelets {

class PrivateParams {
 public:
  explicit PrivateParams(const ros::NodeHandle& private_nh) {
    if (!private_nh.getParam(private_nh.getNamespace(), values_)) values_ = XmlRpc::XmlRpcValue();
  }

  template <class T>
  void param(const std::string& name, T& value, const T& fallback) const {
    const XmlRpc::XmlRpcValue* v = find(name);
    if (!v || !convert(*v, value)) value = fallback;
  }

 private:
  // name may have '/'-separated parts (a nested namespace).
  const XmlRpc::XmlRpcValue* find(const std::string& name) const {
    const XmlRpc::XmlRpcValue* at = &values_;
    size_t begin = 0;
    while (begin <= name.size()) {
      const size_t end = std::min(name.find('/', begin), name.size());
      const std::string part = name.substr(begin, end - begin);
      if (at->getType() != XmlRpc::XmlRpcValue::TypeStruct || !at->hasMember(part)) return nullptr;
      at = &(*const_cast<XmlRpc::XmlRpcValue*>(at))[part];
      begin = end + 1;
    }
    return at;
  }
  static bool convert(const XmlRpc::XmlRpcValue& v, double& out) {
    auto& value = const_cast<XmlRpc::XmlRpcValue&>(v);
    if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble) return out = static_cast<double>(value), true;
    if (v.getType() == XmlRpc::XmlRpcValue::TypeInt) return out = static_cast<int>(value), true;
    return false;
  }
  static bool convert(const XmlRpc::XmlRpcValue& v, int& out) {
    auto& value = const_cast<XmlRpc::XmlRpcValue&>(v);
    if (v.getType() == XmlRpc::XmlRpcValue::TypeInt) return out = static_cast<int>(value), true;
    if (v.getType() != XmlRpc::XmlRpcValue::TypeDouble) return false;
    const double d = static_cast<double>(value);
    if (!(std::abs(d) < std::numeric_limits<int>::max())) return false;
    return out = static_cast<int>(d), true;
  }
  static bool convert(const XmlRpc::XmlRpcValue& v, bool& out) {
    if (v.getType() != XmlRpc::XmlRpcValue::TypeBoolean) return false;
    return out = static_cast<bool>(const_cast<XmlRpc::XmlRpcValue&>(v)), true;
  }
  static bool convert(const XmlRpc::XmlRpcValue& v, std::string& out) {
    if (v.getType() != XmlRpc::XmlRpcValue::TypeString) return false;
    return out = static_cast<std::string>(const_cast<XmlRpc::XmlRpcValue&>(v)), true;
  }

  XmlRpc::XmlRpcValue values_;
};

inline slam::RobotSlamParams robotSlamParamsFrom(const PrivateParams& params) {
  slam::RobotSlamParams p;
  for (const slam::NamedParam& named : slam::robotSlamParams(p))
    std::visit([&](auto* field) { params.param(named.name, *field, *field); }, named.field);
  return p;
}

}  // namespace mrslam::nodelets
