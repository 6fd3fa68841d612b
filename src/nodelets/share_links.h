// How long ago data last arrived on each connection this process holds to a publisher of the
// share topics: the node's own XML-RPC server lists the connections (getBusInfo, what `rosnode
// info` asks: publisher URI, topic, transport info naming the socket; roscpp keeps the function
// itself private), the kernel keeps the time per socket (TCP_INFO; a connection being opened:
// see linkSilence). roscpp's per-connection byte counts (getBusStats) cannot be used:
// Subscription::getStats (ros_comm 1.15) writes every connection into the same slot, so it
// reports one publisher per topic.
#pragma once

#include <netinet/in.h>
#include <ros/network.h>
#include <ros/this_node.h>
#include <ros/xmlrpc_manager.h>
#include <sys/socket.h>
#include <xmlrpcpp/XmlRpcClient.h>
#include <xmlrpcpp/XmlRpcException.h>

#include <algorithm>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "mrslam/tcpros_link.h"

namespace mrslam::nodelets {

// This end's port of socket `fd`, or -1.
inline int localPortOf(int fd) {
  sockaddr_storage address{};
  socklen_t length = sizeof(address);
  if (getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) return -1;
  if (address.ss_family == AF_INET) return ntohs(reinterpret_cast<const sockaddr_in&>(address).sin_port);
  if (address.ss_family == AF_INET6) return ntohs(reinterpret_cast<const sockaddr_in6&>(address).sin6_port);
  return -1;
}

// This node's connections as its XML-RPC server lists them (a call over the loopback to the
// server's own thread), or an empty list.
inline XmlRpc::XmlRpcValue ownBusInfo() {
  XmlRpc::XmlRpcValue args, result, info;
  info.setSize(0);
  std::string host;
  uint32_t port = 0;
  if (!ros::network::splitURI(ros::XMLRPCManager::instance()->getServerURI(), host, port)) return info;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  args[0] = ros::this_node::getName();
  try {
    if (client.execute("getBusInfo", args, result) && result.getType() == XmlRpc::XmlRpcValue::TypeArray &&
        result.size() == 3 && static_cast<int>(result[0]) == 1)
      info = result[2];
  } catch (const XmlRpc::XmlRpcException&) {
  }
  client.close();
  return info;
}

// When each connection still being opened was first seen (wall s), by (descriptor, local port).
using OpeningSince = std::map<std::pair<int, int>, double>;

// Seconds since data last arrived from each publisher (by its XML-RPC URI) of any of `topics`,
// over the freshest of its TCP connections (linkSilence: a connection being opened counts from
// when it was first seen opening, kept in `opening_since` across calls at wall time `now`; the
// entries of connections no longer opening are dropped). Publishers without an open TCP
// connection are missing; so are connections whose socket cannot be read (then nothing is known
// of them).
inline std::map<std::string, double> shareLinkSilence(const std::vector<std::string>& topics,
                                                      OpeningSince& opening_since, double now) {
  XmlRpc::XmlRpcValue info = ownBusInfo();
  std::map<std::string, double> silence;
  OpeningSince still_opening;
  try {
    for (int i = 0; i < info.size(); ++i) {
      XmlRpc::XmlRpcValue& connection = info[i];  // [id, publisher URI, direction, transport, topic, connected, info]
      if (connection.size() < 7 || static_cast<std::string>(connection[2]) != "i") continue;
      if (std::find(topics.begin(), topics.end(), static_cast<std::string>(connection[4])) == topics.end()) continue;
      const auto socket = parseTcprosInfo(connection[6]);
      if (!socket || localPortOf(socket->fd) != socket->local_port) continue;  // closed, or the number reused
      const std::optional<TcpSocketState> tcp = tcpSocketState(socket->fd);
      if (!tcp) continue;
      double opening_for = 0;
      if (tcp->opening) {
        const std::pair<int, int> key{socket->fd, socket->local_port};
        const auto seen = opening_since.find(key);
        const double since = seen != opening_since.end() ? seen->second : now;
        still_opening[key] = since;
        opening_for = now - since;
      }
      const std::string uri = connection[1];
      const double silent_s = linkSilence(tcp->opening, tcp->last_data_recv_ms, opening_for);
      const auto known = silence.find(uri);
      silence[uri] = known == silence.end() ? silent_s : std::min(known->second, silent_s);
    }
  } catch (const XmlRpc::XmlRpcException&) {
    // An entry of another shape: what was read so far stands, and the entries not reached keep
    // their first sighting.
    still_opening.insert(opening_since.begin(), opening_since.end());
  }
  opening_since.swap(still_opening);
  return silence;
}

}  // namespace mrslam::nodelets
