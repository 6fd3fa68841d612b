// The ROS-free parts of the multi-robot stack: peer bookkeeping (discovery, re-estimation,
// hysteresis, the tf frame convention) and the OctoMap export, on real maps.
#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "mrslam/cell_codec.h"
#include "mrslam/fusion/peer_quarantine.h"
#include "mrslam/fusion/peer_registry.h"
#include "mrslam/map_io.h"
#include "mrslam/octomap_export.h"
#include "mrslam/publisher_claim.h"
#include "mrslam/scan_stamp_gate.h"
#include "mrslam/tcpros_link.h"
#include "test_data.h"

namespace mrslam::fusion {
namespace {

std::shared_ptr<const OccupancyGrid> realMap() {
  static const auto map = std::make_shared<const OccupancyGrid>(loadMap(test::referenceMap("intel")));
  return map;
}

// A map summary with `extra` more known cells (and so another content).
MapSummary grown(const MapSummary& s, size_t extra) { return {s.known_cells + extra, s.content ^ (extra * 7919 + 1)}; }

FusionResult estimate(bool accepted, Pose2D pose, double v) {
  FusionResult r;
  r.accepted = accepted;
  r.pose = pose;
  r.verdict.acceptance = v;
  r.verdict.accepted = accepted;
  r.verdict.reason = accepted ? "" : "test rejection";
  return r;
}

TEST(PeerRegistry, DiscoversPeersAndReEstimatesOnlyWhenMapsGrow) {
  PeerRegistry registry("robot2");
  const MapSummary own = summarize(*realMap());
  EXPECT_FALSE(registry.nextToEstimate(own, 0.0));
  EXPECT_TRUE(registry.updatePeer("robot1", realMap(), 1, 0.0));   // discovered
  EXPECT_FALSE(registry.updatePeer("robot1", realMap(), 2, 1.0));  // known
  EXPECT_EQ(registry.nextToEstimate(own, 1.0).value_or(""), "robot1");  // never estimated
  registry.applyEstimate("robot1", estimate(true, {1, 2, 0.1}, 0.98), own, 2.0);
  EXPECT_FALSE(registry.nextToEstimate(own, 3.0)) << "nothing grew";
  EXPECT_FALSE(registry.nextToEstimate(own, 100.0)) << "nothing changed, however long ago";
  EXPECT_TRUE(registry.nextToEstimate(grown(own, own.known_cells / 5), 3.0)) << "our map grew by 20 %";
  EXPECT_FALSE(registry.nextToEstimate(grown(own, 10), 3.0)) << "a small change waits for the refresh period";
  EXPECT_TRUE(registry.nextToEstimate(grown(own, 10), 13.0)) << "...and is estimated after it";
  EXPECT_FALSE(registry.nextToEstimate(MapSummary{1000, 1}, 100.0)) << "maps this small are not estimated";
}

TEST(PeerRegistry, RefreshRunsOnTheSchedulingClockAndReportsCurrentEstimates) {
  // A bag's clock stops at its end: estimates stamped with it must still be refreshed on the
  // (wall) scheduling clock, or the final maps would never be merged.
  PeerRegistry registry("robot2");
  const MapSummary own = summarize(*realMap());
  registry.updatePeer("robot1", realMap(), 1, 50.0);
  EXPECT_FALSE(registry.estimateIsCurrent(registry.peers().at("robot1"), own)) << "never estimated";
  registry.applyEstimate("robot1", estimate(true, {1, 2, 0.1}, 0.98), own, /*stamp*/ 50.0, /*clock*/ 1000.0);
  EXPECT_TRUE(registry.estimateIsCurrent(registry.peers().at("robot1"), own));
  EXPECT_FALSE(registry.estimateIsCurrent(registry.peers().at("robot1"), grown(own, 10))) << "our map changed";
  EXPECT_FALSE(registry.nextToEstimate(grown(own, 10), 1005.0)) << "within the refresh period of the clock";
  EXPECT_TRUE(registry.nextToEstimate(grown(own, 10), 1010.0)) << "refresh period passed on the clock";
  EXPECT_EQ(registry.peers().at("robot1").last_attempt.stamp, 50.0) << "the estimate keeps its stamp";
}

TEST(PeerRegistry, MovedWallsAreAChangeAndAHeldTransformIsNotCurrentAfterARejection) {
  // A loop closure moves walls without adding known cells: the map's content changed all the
  // same, and the estimate made on the old map no longer describes it.
  PeerRegistry registry("robot2");
  const MapSummary own = summarize(*realMap());
  registry.updatePeer("robot1", realMap(), 1, 0.0);
  registry.applyEstimate("robot1", estimate(true, {1, 2, 0.1}, 0.98), own, 1.0);
  ASSERT_TRUE(registry.estimateIsCurrent(registry.peers().at("robot1"), own));
  auto moved = std::make_shared<OccupancyGrid>(*realMap());
  auto occupied = std::find_if(moved->data.begin(), moved->data.end(), [](int8_t v) { return v > 50; });
  auto free = std::find_if(moved->data.begin(), moved->data.end(), [](int8_t v) { return v == 0; });
  ASSERT_TRUE(occupied != moved->data.end() && free != moved->data.end());
  std::iter_swap(occupied, free);
  registry.updatePeer("robot1", moved, 2, 2.0);
  EXPECT_EQ(registry.peers().at("robot1").summary.known_cells, own.known_cells) << "as many known cells as before";
  EXPECT_FALSE(registry.estimateIsCurrent(registry.peers().at("robot1"), own)) << "yet the content changed";
  EXPECT_TRUE(registry.nextToEstimate(own, 12.0)) << "re-estimated after the refresh period";
  // A rejection on the new maps: the transform in use is kept (hysteresis) but is not current.
  registry.applyEstimate("robot1", estimate(false, {}, 0.9), own, 12.0);
  EXPECT_TRUE(registry.peers().at("robot1").accepted);
  EXPECT_FALSE(registry.estimateIsCurrent(registry.peers().at("robot1"), own));
}

TEST(PeerRegistry, HysteresisRefinesKeepsAndRevokes) {
  PeerRegistry registry("robot2");
  const MapSummary own = summarize(*realMap());
  registry.updatePeer("robot1", realMap(), 1, 0.0);
  EXPECT_TRUE(registry.applyEstimate("robot1", estimate(true, {1, 2, 0.1}, 0.98), own, 1.0));
  // A nearby estimate refines it, even with a slightly lower V.
  EXPECT_TRUE(registry.applyEstimate("robot1", estimate(true, {1.1, 2, 0.11}, 0.979), own, 2.0));
  EXPECT_NEAR(registry.peers().at("robot1").accepted->pose.x, 1.1, 1e-12);
  // Elsewhere and not clearly better: kept.
  EXPECT_FALSE(registry.applyEstimate("robot1", estimate(true, {8, -3, 2.0}, 0.985), own, 3.0));
  EXPECT_NEAR(registry.peers().at("robot1").accepted->pose.x, 1.1, 1e-12);
  // Elsewhere and clearly better: switched.
  EXPECT_TRUE(registry.applyEstimate("robot1", estimate(true, {8, -3, 2.0}, 0.995), own, 4.0));
  EXPECT_NEAR(registry.peers().at("robot1").accepted->pose.x, 8.0, 1e-12);
  // Two rejections keep it, the third in a row revokes it.
  EXPECT_FALSE(registry.applyEstimate("robot1", estimate(false, {}, 0.9), own, 5.0));
  EXPECT_FALSE(registry.applyEstimate("robot1", estimate(false, {}, 0.9), own, 6.0));
  EXPECT_TRUE(registry.applyEstimate("robot1", estimate(false, {}, 0.9), own, 7.0));
  EXPECT_FALSE(registry.peers().at("robot1").accepted);
}

TEST(PeerRegistry, RestartedPeerIsForgottenAndTheTfParentIsTheSmallestAcceptedIdBelowUs) {
  PeerRegistry registry("robot3");
  const MapSummary own = summarize(*realMap());
  for (const char* id : {"robot1", "robot2", "robot4"}) registry.updatePeer(id, realMap(), 5, 0.0);
  EXPECT_FALSE(registry.parentOf()) << "nothing accepted: robot3/map is a root";
  registry.applyEstimate("robot4", estimate(true, {}, 0.99), own, 1.0);
  EXPECT_FALSE(registry.parentOf()) << "robot4 hangs below robot3, never above";
  registry.applyEstimate("robot2", estimate(true, {}, 0.99), own, 1.0);
  EXPECT_EQ(registry.parentOf().value_or(""), "robot2");
  registry.applyEstimate("robot1", estimate(true, {}, 0.99), own, 1.0);
  EXPECT_EQ(registry.parentOf().value_or(""), "robot1");
  // robot1 restarts (its version counter starts again): a new map frame, nothing carried over.
  EXPECT_TRUE(registry.updatePeer("robot1", realMap(), 1, 2.0));
  EXPECT_FALSE(registry.peers().at("robot1").accepted);
  EXPECT_EQ(registry.parentOf().value_or(""), "robot2");
}

// The four peer maps that once took every robot's manager down (each a std::invalid_argument
// thrown by the fusion and never caught): the nodelet's validator must refuse each of them
// before the fusion sees it, and accept the real map they were made from.
TEST(PeerMapCheck, RefusesExactlyWhatTheFusionWouldRefuse) {
  const FusionParams params;
  const OccupancyGrid& own = *realMap();
  EXPECT_EQ(peerMapProblem(own, own.resolution, params), "");
  EXPECT_NO_THROW(alignMaps(own, own, params));

  OccupancyGrid coarse = own;
  coarse.resolution = 10 * own.resolution;
  OccupancyGrid all_free;
  all_free.width = all_free.height = 300, all_free.resolution = own.resolution;
  all_free.data.assign(300 * 300, 0);
  OccupancyGrid out_of_range = own;
  for (int8_t& v : out_of_range.data)
    if (v < 0) v = 127;
  OccupancyGrid nan_origin = own;
  nan_origin.origin.yaw = std::nan("");
  for (const OccupancyGrid* hostile : {&coarse, &all_free, &out_of_range, &nan_origin}) {
    const std::string problem = peerMapProblem(*hostile, own.resolution, params);
    EXPECT_NE(problem, "");
    EXPECT_EQ(fusionInputProblem(own, *hostile, params).empty(), problem.empty());
    EXPECT_THROW(alignMaps(own, *hostile, params), std::invalid_argument) << problem;
  }
  EXPECT_NE(peerMapProblem(coarse, own.resolution, params).find("differ too much"), std::string::npos);
  EXPECT_EQ(peerMapProblem(coarse, 0.0, params), "") << "resolution unknown yet: only the map itself is checked";
}

// Found by the fuzzer: two maps of a resolution of 1e-270 m passed every check, and a metre
// became 1e270 cells, an int overflow in the similarity search. Such resolutions are refused.
TEST(PeerMapCheck, AbsurdResolutionsAreRefusedBeforeTheSearch) {
  const FusionParams params;
  OccupancyGrid tiny = *realMap(), huge = *realMap();
  tiny.resolution = 1e-270;
  huge.resolution = 1e6;
  for (const OccupancyGrid* g : {&tiny, &huge}) {
    EXPECT_NE(validateGrid(*g).find("outside"), std::string::npos);
    EXPECT_NE(peerMapProblem(*g, 0.0, params), "");
    EXPECT_THROW(alignMaps(*g, *g, params), std::invalid_argument);
  }
}

TEST(PeerQuarantine, APeerRefusedSeveralTimesInARowIsNotHeardForAWhile) {
  PeerQuarantine q({/*bad_maps_in_a_row=*/3, /*period_s=*/60.0});
  EXPECT_FALSE(q.reportBad("robot9", 0.0));
  EXPECT_FALSE(q.reportBad("robot9", 1.0));
  q.reportGood("robot9");  // one good map ends the streak
  EXPECT_FALSE(q.reportBad("robot9", 2.0));
  EXPECT_FALSE(q.reportBad("robot9", 3.0));
  EXPECT_FALSE(q.isQuarantined("robot9", 3.0));
  EXPECT_TRUE(q.reportBad("robot9", 4.0)) << "third refusal in a row";
  EXPECT_TRUE(q.isQuarantined("robot9", 63.9));
  EXPECT_FALSE(q.isQuarantined("robot1", 10.0)) << "only the peer that sent them";
  EXPECT_EQ(q.quarantined(10.0), std::vector<std::string>{"robot9"});
  EXPECT_FALSE(q.isQuarantined("robot9", 64.0)) << "heard again after the period";
  EXPECT_FALSE(q.reportBad("robot9", 65.0)) << "...from scratch";
}

TEST(PeerRegistry, ParametersOutOfRangeAreNamedWithTheirValue) {
  EXPECT_EQ(peerRegistryParamsProblem(PeerRegistryParams{}), "") << "the defaults are usable";
  auto problem = [](auto change) {
    PeerRegistryParams p;
    change(p);
    return peerRegistryParamsProblem(p);
  };
  EXPECT_EQ(problem([](PeerRegistryParams& p) { p.relay_agree_m = -0.1; }).rfind("relay_agree_m must be > 0", 0), 0u);
  EXPECT_EQ(problem([](PeerRegistryParams& p) { p.relay_min_vias = 9; }).rfind("relay_min_vias must be in [0, 8]", 0), 0u);
  EXPECT_EQ(problem([](PeerRegistryParams& p) { p.refresh_period = std::nan(""); }).rfind("refresh_period", 0), 0u);
  EXPECT_EQ(problem([](PeerRegistryParams& p) { p.revoke_after_rejections = 0; }).rfind("revoke_after_rejections", 0), 0u);
  EXPECT_EQ(problem([](PeerRegistryParams& p) { p.relay_min_vias = 0; }), "") << "0 switches relays off";
}

TEST(PeerRegistry, RobotIdsMustBeTfPrefixes) {
  for (const char* good : {"robot1", "R2", "robot_3", "a"}) EXPECT_TRUE(isValidRobotId(good)) << good;
  for (const char* bad : {"", "/robot0", "a/evil robot", "1robot", "_robot", "robot-1", "robot 1", "robot\n"})
    EXPECT_FALSE(isValidRobotId(bad)) << bad;
  EXPECT_FALSE(isValidRobotId(std::string(65, 'r')));
}

}  // namespace
}  // namespace mrslam::fusion

namespace mrslam {
namespace {

// The inter-robot encoding of a grid's cells: lossless on a real map, several times smaller,
// and a peer's stream inflates to exactly the cells its header claims or is refused.
TEST(CellCodec, RealMapRoundTripsSmallerAndBadStreamsAreRefused) {
  const OccupancyGrid map = loadMap(test::referenceMap("intel"));
  const std::vector<uint8_t> packed = compressCells(map.data.data(), map.data.size(), 1);
  std::printf("Intel reference map: %zu cells -> %zu bytes (%.1fx)\n", map.data.size(), packed.size(),
              static_cast<double>(map.data.size()) / packed.size());
  EXPECT_LT(packed.size() * 5, map.data.size());
  std::vector<int8_t> cells;
  ASSERT_EQ(decompressCells(packed.data(), packed.size(), map.data.size(), cells), "");
  EXPECT_EQ(cells, map.data);

  EXPECT_NE(decompressCells(packed.data(), packed.size(), map.data.size() - 1, cells).find("more than"), std::string::npos);
  EXPECT_TRUE(cells.empty());
  EXPECT_NE(decompressCells(packed.data(), packed.size(), map.data.size() + 1, cells).find("holds"), std::string::npos);
  EXPECT_NE(decompressCells(packed.data(), packed.size() / 2, map.data.size(), cells).find("ends early"), std::string::npos);
  std::vector<uint8_t> garbage(packed.begin(), packed.end());
  for (size_t i = 2; i < garbage.size(); i += 7) garbage[i] ^= 0x5a;
  EXPECT_NE(decompressCells(garbage.data(), garbage.size(), map.data.size(), cells), "");
  // A bomb: a few hundred bytes that would inflate to 100 MB, claimed as 1000 cells.
  const std::vector<int8_t> zeros(100'000'000, 0);
  const std::vector<uint8_t> bomb = compressCells(zeros.data(), zeros.size(), 9);
  EXPECT_LT(bomb.size(), 200'000u);
  EXPECT_NE(decompressCells(bomb.data(), bomb.size(), 1000, cells), "");
  EXPECT_TRUE(cells.empty());
}

TEST(PublisherClaim, TheFirstPublisherHoldsANameUntilItFallsSilent) {
  PublisherClaim claim;
  EXPECT_FALSE(claim.heldByAnother("/robot1/laser_driver", 0.0, 5.0)) << "nobody holds it yet";
  claim.take("/robot1/laser_driver", 0.0);
  EXPECT_FALSE(claim.heldByAnother("/robot1/laser_driver", 1.0, 5.0));
  claim.take("/robot1/laser_driver", 1.0);
  EXPECT_TRUE(claim.heldByAnother("/intruder", 3.0, 5.0));
  EXPECT_TRUE(claim.heldByAnother("/intruder", 5.9, 5.0)) << "silent for 4.9 s of 5";
  EXPECT_FALSE(claim.heldByAnother("/laser_driver_restarted", 6.1, 5.0)) << "the holder fell silent";
  claim.take("/laser_driver_restarted", 6.1);
  EXPECT_EQ(claim.holder(), "/laser_driver_restarted");
  EXPECT_TRUE(claim.heldByAnother("/robot1/laser_driver", 6.2, 5.0));
}

// The transport info roscpp 1.15 gives a subscriber's TCP connection (TransportTCP), as
// `rosnode info` printed it on the multi-host harness, and lines that must not be taken for one.
TEST(TcprosLink, FindsTheSocketOfATcpConnectionAndNothingElse) {
  const auto s = parseTcprosInfo("TCPROS connection on port 46571 to [10.213.0.3:39211 on socket 57]");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->local_port, 46571);
  EXPECT_EQ(s->fd, 57);
  const auto v6 = parseTcprosInfo("TCPROS connection on port 40000 to [fe80::1%eth0:39211 on socket 9]");
  ASSERT_TRUE(v6);
  EXPECT_EQ(v6->fd, 9);
  EXPECT_FALSE(parseTcprosInfo("INTRAPROCESS"));
  EXPECT_FALSE(parseTcprosInfo("UDPROS connection on port 46571 to [10.213.0.3:39211 on socket 57]"));
  EXPECT_FALSE(parseTcprosInfo("TCPROS connection on port -1 to [10.213.0.3:39211 on socket 57]"));
  EXPECT_FALSE(parseTcprosInfo("TCPROS connection on port 46571 to [TCPServer Socket]"));
  EXPECT_FALSE(parseTcprosInfo("TCPROS connection on port 46571 to [10.213.0.3:39211 on socket 57"));
  EXPECT_FALSE(parseTcprosInfo("TCPROS connection on port 46571 to [10.213.0.3:39211 on socket x]"));
  EXPECT_FALSE(parseTcprosInfo(""));
}

// A stale peer whose connection still receives is behind a slow link: left alone.
TEST(TcprosLink, OnlyALinkWithNothingArrivingIsDead) {
  EXPECT_TRUE(linkIsDead(std::nullopt, 10.0)) << "no connection open";
  EXPECT_TRUE(linkIsDead(12.5, 10.0)) << "nothing for longer than stale_after";
  EXPECT_FALSE(linkIsDead(0.3, 10.0)) << "a map still crossing a slow link";
  EXPECT_FALSE(linkIsDead(10.0, 10.0));
}

// A connection whose SYN is not answered yet is being opened, not silent for the hours since
// boot the kernel reports for it (19584 s on the multi-host harness, 6 s after the re-make that
// opened it): dead only once it has been opening for longer than stale_after.
TEST(TcprosLink, AConnectionBeingOpenedIsSilentOnlyAsLongAsItHasBeenOpening) {
  const uint32_t since_boot_ms = 19584200;
  EXPECT_DOUBLE_EQ(linkSilence(false, 400, 0.0), 0.4);
  EXPECT_DOUBLE_EQ(linkSilence(false, since_boot_ms, 0.0), 19584.2) << "established: the kernel's figure stands";
  EXPECT_DOUBLE_EQ(linkSilence(true, since_boot_ms, 6.0), 6.0);
  EXPECT_FALSE(linkIsDead(linkSilence(true, since_boot_ms, 6.0), 10.0));
  EXPECT_TRUE(linkIsDead(linkSilence(true, since_boot_ms, 11.0), 10.0)) << "opening for longer than stale_after";
}

// What linkSilence relies on, asked of this machine's kernel over the loopback: a listener
// whose accept queue is full drops further SYNs, so those connections stay being opened (as
// after an outage, SYNs retried after 1, 2, 4 s); the one the queue took is established, and
// before any data its last_data_recv counts from then. (The opening ones count from boot.)
TEST(TcprosLink, TheKernelTellsAConnectionBeingOpenedFromAnEstablishedOne) {
  const int listener = socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(listener, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(listener, reinterpret_cast<sockaddr*>(&address), sizeof(address)), 0);
  ASSERT_EQ(listen(listener, 0), 0);  // an accept queue of one, never accepted from
  socklen_t length = sizeof(address);
  ASSERT_EQ(getsockname(listener, reinterpret_cast<sockaddr*>(&address), &length), 0);
  std::vector<int> clients;
  for (int k = 0; k < 4; ++k) {
    clients.push_back(socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK, 0));
    ASSERT_GE(clients.back(), 0);
    connect(clients.back(), reinterpret_cast<sockaddr*>(&address), sizeof(address));  // EINPROGRESS
  }
  usleep(200000);
  int opening = 0, established = 0;
  for (int fd : clients) {
    const std::optional<TcpSocketState> state = tcpSocketState(fd);
    ASSERT_TRUE(state);
    if (state->opening) {
      ++opening;
    } else {
      ++established;
      EXPECT_LT(state->last_data_recv_ms, 5000u) << "established without data: counted from the connect";
    }
  }
  EXPECT_GE(opening, 1) << "SYNs beyond a full accept queue are dropped";
  EXPECT_GE(established, 1);
  EXPECT_FALSE(tcpSocketState(-1));
  for (int fd : clients) close(fd);
  close(listener);
}

// Intel's scans as scripts/bench_multi's bags carry them (one every ~3.3 s), played while the
// clock stood still for 22 s as rosbag play's /clock did under load in the multi_robot rostest.
TEST(ScanStampGate, ScansInStrideAreUsedWhileTheClockStallsAndAStrayStampIsRefused) {
  ScanStampGate gate(ScanStampRules{});
  const double clock = 145.53;
  double t = 145.6;
  for (int i = 0; i < 7; ++i, t += 3.3) {
    const StampVerdict v = gate.check(t, clock);
    EXPECT_EQ(v.kind, StampVerdict::Kind::kUse) << "scan " << i << " at " << t << ": " << v.reason;
    gate.used(t);
  }
  EXPECT_GT(gate.check(t, clock).clock_lag, 20.0);
  const StampVerdict stray = gate.check(t + 3600, clock);
  EXPECT_EQ(stray.kind, StampVerdict::Kind::kRefuse) << "an hour after the last scan";
  EXPECT_NE(stray.reason.find("after the last scan"), std::string::npos) << stray.reason;
  EXPECT_EQ(gate.check(t, t - 1).kind, StampVerdict::Kind::kUse) << "the next scan after the stray one";
  ScanStampGate fresh(ScanStampRules{});
  EXPECT_EQ(fresh.check(clock + 11, clock).kind, StampVerdict::Kind::kRefuse) << "no scan yet: the clock is all there is";
  EXPECT_EQ(fresh.check(clock + 11, 0).kind, StampVerdict::Kind::kUse) << "no clock and no scan yet";
  EXPECT_EQ(fresh.check(0, clock).kind, StampVerdict::Kind::kRefuse) << "stamped 0";
}

TEST(ScanStampGate, TimeGoingBackIsRefusedUntilItDoesSoSeveralScansInARow) {
  ScanStampGate gate(ScanStampRules{1.0, 3, 10.0});
  gate.used(200.0);
  EXPECT_EQ(gate.check(199.5, 200).kind, StampVerdict::Kind::kUse) << "within max_time_jump";
  EXPECT_EQ(gate.check(100.0, 200).kind, StampVerdict::Kind::kRefuse);
  EXPECT_EQ(gate.check(200.5, 200).kind, StampVerdict::Kind::kUse) << "one stray old stamp breaks no run";
  EXPECT_EQ(gate.check(100.0, 200).kind, StampVerdict::Kind::kRefuse);
  EXPECT_EQ(gate.check(100.1, 200).kind, StampVerdict::Kind::kRefuse);
  const StampVerdict restart = gate.check(100.2, 200);
  EXPECT_EQ(restart.kind, StampVerdict::Kind::kRestart) << "three scans in a row: the bag restarted";
  EXPECT_FALSE(gate.last()) << "the old scans are forgotten";
  EXPECT_EQ(gate.check(100.3, 100.3).kind, StampVerdict::Kind::kUse);
}

TEST(OctomapExport, RealMapWallsBecomeOccupiedColumnsAndFreeCellsFree) {
  const OccupancyGrid grid = loadMap(test::referenceMap("intel"));
  const std::string path = ::testing::TempDir() + "/intel.bt";
  ASSERT_GT(saveOctomap(grid, path, 0.5), 0u);
  octomap::OcTree tree(path);
  ASSERT_GT(tree.size(), 0u);
  EXPECT_NEAR(tree.getResolution(), grid.resolution, 1e-9);
  int occupied = 0, free = 0, checked = 0;
  for (int row = 0; row < grid.height && checked < 4000; row += 7)
    for (int col = 0; col < grid.width && checked < 4000; col += 7) {
      const int v = grid.at(col, row);
      if (v < 0 || (v > 25 && v < 65)) continue;
      const octomap::point3d p(static_cast<float>(grid.origin.x + (col + 0.5) * grid.resolution),
                               static_cast<float>(grid.origin.y + (row + 0.5) * grid.resolution), 0.3f);
      const octomap::OcTreeNode* node = tree.search(p);
      ASSERT_NE(node, nullptr);
      ++checked;
      if (tree.isNodeOccupied(node) == (v >= 65)) (v >= 65 ? occupied : free)++;
      else ADD_FAILURE() << "cell " << col << "," << row << " value " << v;
    }
  EXPECT_GT(occupied, 20);
  EXPECT_GT(free, 1000);
  std::remove(path.c_str());
  EXPECT_THROW(saveOctomap(grid, "/nonexistent/dir/x.bt"), std::runtime_error);
}

}  // namespace
}  // namespace mrslam
