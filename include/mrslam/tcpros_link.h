// Which socket carries a subscriber's connection to a publisher, read from the line roscpp gives
// for it ("TCPROS connection on port L to [host:port on socket S]", TransportTCP's transport
// info, as `rosnode info` prints it), and whether such a link is dead or only slow.
//
// Why: a peer whose map has not arrived for stale_after may still be sending over a slow link
// (data keeps arriving on its connection) or may be gone (nothing arrives: its link is down, or
// came back while TCP still backs its retransmissions off). Only the second calls for a new
// connection, and re-making the share subscription cuts every transfer in flight.
#pragma once

#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>

namespace mrslam {

struct TcprosSocket {
  int local_port = 0;  // this end's port, to check that the descriptor still is that connection
  int fd = -1;         // the socket's descriptor in this process
};

// The socket of a TCPROS connection's transport info; nothing for other transports (an
// intra-process link, UDPROS) or a line of another shape.
inline std::optional<TcprosSocket> parseTcprosInfo(const std::string& info) {
  const std::string head = "TCPROS connection on port ";
  const size_t on_socket = info.rfind(" on socket ");
  if (info.compare(0, head.size(), head) != 0 || info.find(" to [") == std::string::npos ||
      on_socket == std::string::npos || info.back() != ']')
    return std::nullopt;
  TcprosSocket s;
  char close = 0;
  if (std::sscanf(info.c_str() + head.size(), "%d", &s.local_port) != 1 ||
      std::sscanf(info.c_str() + on_socket, " on socket %d%c", &s.fd, &close) != 2 || close != ']')
    return std::nullopt;
  if (s.local_port <= 0 || s.local_port > 65535 || s.fd < 0) return std::nullopt;
  return s;
}

// What the kernel says of a TCP socket (TCP_INFO): whether it is still being opened (SYN sent,
// not answered), and ms since data last arrived (see linkSilence). Nothing when `fd` is not a
// TCP socket of this process.
struct TcpSocketState {
  bool opening = false;
  uint32_t last_data_recv_ms = 0;
};
inline std::optional<TcpSocketState> tcpSocketState(int fd) {
  tcp_info tcp{};
  socklen_t length = sizeof(tcp);
  if (getsockopt(fd, IPPROTO_TCP, TCP_INFO, &tcp, &length) != 0) return std::nullopt;
  return TcpSocketState{tcp.tcpi_state == TCP_SYN_SENT, tcp.tcpi_last_data_recv};
}

// How long nothing has arrived on a connection, from the kernel's TCP_INFO. The kernel counts
// last_data_recv from the last data or, before any, from when the connection was established.
// A connection still being opened (`opening`: its SYN not answered yet, which TCP backs off
// for seconds after an outage) has neither, and the figure counts from boot: hours, as on the
// multi-host harness (19584 s), where it made a connection being opened look dead. Its silence
// is how long this process has seen it opening, `opening_for_s`.
inline double linkSilence(bool opening, uint32_t last_data_recv_ms, double opening_for_s) {
  return opening ? opening_for_s : last_data_recv_ms / 1000.0;
}

// A peer silent for stale_after gets its connection re-made only when its link is dead too:
// no connection to it is open (`link_silent_s` empty), or nothing has arrived on it for
// stale_after. A link still receiving is a slow one: re-making it would throw away the map in
// flight and start it again.
inline bool linkIsDead(std::optional<double> link_silent_s, double stale_after) {
  return !link_silent_s || *link_silent_s > stale_after;
}

}  // namespace mrslam
