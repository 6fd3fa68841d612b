// What the ROS master knows about a topic's publishers (getSystemState) and where a node
// listens (lookupNode). Blocking XML-RPC calls: never made while holding a lock a callback
// needs.
#pragma once

#include <ros/master.h>
#include <ros/names.h>
#include <xmlrpcpp/XmlRpcException.h>

#include <algorithm>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace mrslam::nodelets {

// The nodes registered as publishers of any of `topics` (resolved), or nothing when the master
// cannot be asked.
inline std::optional<std::set<std::string>> publishersOf(const std::vector<std::string>& topics) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, false)) return std::nullopt;
  try {
    std::set<std::string> nodes;
    XmlRpc::XmlRpcValue& publishers = payload[0];
    for (int i = 0; i < publishers.size(); ++i) {
      const std::string topic = publishers[i][0];
      if (std::find(topics.begin(), topics.end(), topic) == topics.end()) continue;
      for (int j = 0; j < publishers[i][1].size(); ++j) nodes.insert(static_cast<std::string>(publishers[i][1][j]));
    }
    return nodes;
  } catch (const XmlRpc::XmlRpcException&) {
    return std::nullopt;
  }
}

// The XML-RPC URI of `node` (a publisher's caller id), or nothing when the master does not know
// it or cannot be asked.
inline std::optional<std::string> uriOfNode(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return std::nullopt;
  try {
    return static_cast<std::string>(payload);
  } catch (const XmlRpc::XmlRpcException&) {
    return std::nullopt;
  }
}

}  // namespace mrslam::nodelets
