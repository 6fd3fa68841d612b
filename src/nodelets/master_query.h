// What the ROS master knows about a topic's publishers (getSystemState). A blocking XML-RPC
// call: never made while holding a lock a callback needs.
#pragma once

#include <ros/master.h>
#include <ros/names.h>
#include <xmlrpcpp/XmlRpcException.h>

#include <optional>
#include <set>
#include <string>

namespace mrslam::nodelets {

// The nodes registered as publishers of `topic` (resolved), or nothing when the master cannot
// be asked.
inline std::optional<std::set<std::string>> publishersOf(const std::string& topic) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, false)) return std::nullopt;
  try {
    const std::string resolved = ros::names::resolve(topic);
    XmlRpc::XmlRpcValue& publishers = payload[0];
    for (int i = 0; i < publishers.size(); ++i) {
      if (static_cast<std::string>(publishers[i][0]) != resolved) continue;
      std::set<std::string> nodes;
      for (int j = 0; j < publishers[i][1].size(); ++j) nodes.insert(static_cast<std::string>(publishers[i][1][j]));
      return nodes;
    }
    return std::set<std::string>{};
  } catch (const XmlRpc::XmlRpcException&) {
    return std::nullopt;
  }
}

}  // namespace mrslam::nodelets
