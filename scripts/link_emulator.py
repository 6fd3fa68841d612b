"""A star network of separate hosts on this machine, with shaped wireless-like links.

    link_emulator.py --name PREFIX --robots N [--delay-ms D] [--loss P] [--rate-kbit R]
                     [--queue-ms Q] [--seed S] [--stats FILE]

Creates one network namespace per host, PREFIX-0 for the ROS master and PREFIX-1 .. PREFIX-N
for the robots, each with a tun device and its own address 10.213.0.(k + 1)/24 (addresses
exist inside these namespaces only). This process is the access point between them: it reads
every packet a host sends and writes it into the addressed host's device, after passing it
through the sender's link. A robot's link (what it sends, as tc netem shapes a device's
egress) loses packets with probability P (seeded), serialises them at R kbit/s behind a
tail-drop queue of Q ms and delays them by D ms; its replies cross the other host's link, so
a robot-to-robot round trip takes 2 D and either direction loses P. The master's link is
ideal (a base station). With D = 0, P = 0 and R = 0 every link is ideal.

Why not veth + tc netem: the kernel of the machines this runs on has no sch_netem (nor an
iptables loss match), and a user-space access point behaves the same on every kernel that has
network namespaces and tun. If either is missing, the first line on stderr says which and the
exit status is 77 (skipped), before anything is created.

SIGUSR1 cuts one robot's link in both directions, as when it drives out of range: the robot
named in the file --cut-file (its number), else the last; the next SIGUSR1 brings it back.
SIGUSR2 writes the figures so far to --stats with the suffix ".snapshot".

Prints "ready" on stdout once every namespace is up. On SIGTERM/SIGINT it deletes the
namespaces, writes per-robot link figures to --stats (bytes sent and received, packets the
link lost, packets dropped by its full queue) and exits 0.
"""
import argparse
import fcntl
import heapq
import os
import random
import select
import signal
import struct
import subprocess
import sys
import time

TUNSETIFF = 0x400454CA
IFF_TUN = 0x0001
IFF_NO_PI = 0x1000
SKIPPED = 77


def address(host):
    return f"10.213.0.{host + 1}"


class Link:
    """One direction of one host's link: loss, a rate with a tail-drop queue, a delay."""

    def __init__(self, delay_s, loss, rate_bps, queue_s, rng):
        self.delay_s, self.loss, self.rate_bps, self.queue_s = delay_s, loss, rate_bps, queue_s
        self.rng = rng
        self.free_at = 0.0  # when the last queued packet has left the sender
        self.bytes = self.packets = self.lost = self.queue_drops = 0

    def departure(self, now, size):
        """When a packet handed over now arrives at the far end, or None if it is dropped."""
        if self.loss > 0 and self.rng.random() < self.loss:
            self.lost += 1
            return None
        start = max(now, self.free_at)
        if self.rate_bps > 0:
            if start - now > self.queue_s:
                self.queue_drops += 1
                return None
            self.free_at = start + size * 8.0 / self.rate_bps
        else:
            self.free_at = start
        self.bytes += size
        self.packets += 1
        return self.free_at + self.delay_s


def run(command):
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def open_tun(name):
    fd = os.open("/dev/net/tun", os.O_RDWR | os.O_NONBLOCK)
    fcntl.ioctl(fd, TUNSETIFF, struct.pack("16sH", name.encode(), IFF_TUN | IFF_NO_PI))
    return fd


def missing_feature():
    """Why this machine cannot host the network, or None."""
    if os.geteuid() != 0:
        return "not root (network namespaces need CAP_NET_ADMIN)"
    if not os.path.exists("/dev/net/tun"):
        return "no /dev/net/tun (kernel without tun)"
    probe = f"mrslam-probe-{os.getpid()}"
    result = subprocess.run(["ip", "netns", "add", probe], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if result.returncode != 0:
        return "cannot create a network namespace: " + result.stderr.strip()
    subprocess.run(["ip", "netns", "del", probe], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return None


class AccessPoint:
    def __init__(self, args):
        self.args = args
        rng = random.Random(args.seed)
        shaped = dict(delay_s=args.delay_ms / 1000.0, loss=args.loss, rate_bps=args.rate_kbit * 1000.0,
                      queue_s=args.queue_ms / 1000.0, rng=rng)
        ideal = dict(delay_s=0.0, loss=0.0, rate_bps=0.0, queue_s=0.0, rng=rng)
        self.hosts = list(range(args.robots + 1))
        self.links = {h: Link(**(ideal if h == 0 else shaped)) for h in self.hosts}
        self.received = {h: 0 for h in self.hosts}
        self.namespaces, self.fds = [], {}
        self.by_address = {}
        self.events = []  # (time, sequence, destination host, packet)
        self.sequence = 0
        self.cut_host = args.robots
        self.cut = False
        self.cut_packets = 0
        self.ready_at = time.monotonic()

    def build(self):
        for h in self.hosts:
            ns, dev = f"{self.args.name}-{h}", f"mrs{os.getpid() % 100000}x{h}"
            run(["ip", "netns", "add", ns])
            self.namespaces.append(ns)
            self.fds[h] = open_tun(dev)
            run(["ip", "link", "set", dev, "netns", ns])
            run(["ip", "-n", ns, "link", "set", "lo", "up"])
            run(["ip", "-n", ns, "addr", "add", address(h) + "/24", "dev", dev])
            run(["ip", "-n", ns, "link", "set", dev, "up"])
            self.by_address[bytes(int(x) for x in address(h).split("."))] = h
        self.host_of_fd = {fd: h for h, fd in self.fds.items()}

    def teardown(self):
        for fd in self.fds.values():
            os.close(fd)
        for ns in self.namespaces:
            subprocess.run(["ip", "netns", "del", ns], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def schedule(self, when, destination, packet):
        self.sequence += 1
        heapq.heappush(self.events, (when, self.sequence, destination, packet))

    def receive(self, source, packet, now):
        if len(packet) < 20 or packet[0] >> 4 != 4:
            return  # IPv4 only (the namespaces have no IPv6 address)
        destination = self.by_address.get(bytes(packet[16:20]))
        if destination is None:
            return
        if self.cut and self.cut_host in (source, destination):
            self.cut_packets += 1
            return
        arrival = self.links[source].departure(now, len(packet))
        if arrival is not None:
            self.schedule(arrival, destination, packet)

    def deliver_due(self, now):
        while self.events and self.events[0][0] <= now:
            _, _, destination, packet = heapq.heappop(self.events)
            try:
                os.write(self.fds[destination], packet)
                self.received[destination] += len(packet)
            except BlockingIOError:
                pass  # the host's own device queue is full: lost, as on a real link

    def serve(self, stop):
        fds = list(self.fds.values())
        while not stop():
            now = time.monotonic()
            timeout = 0.5 if not self.events else max(0.0, min(0.5, self.events[0][0] - now))
            try:
                readable, _, _ = select.select(fds, [], [], timeout)
            except InterruptedError:
                continue
            now = time.monotonic()
            for fd in readable:
                for _ in range(64):  # drain a burst, but let the others speak
                    try:
                        packet = os.read(fd, 65535)
                    except BlockingIOError:
                        break
                    self.receive(self.host_of_fd[fd], packet, now)
            self.deliver_due(time.monotonic())

    def toggle_cut(self):
        if not self.cut and self.args.cut_file and os.path.exists(self.args.cut_file):
            with open(self.args.cut_file, encoding="utf-8") as f:
                named = f.read().strip()
            if named.isdigit() and 1 <= int(named) <= self.args.robots:
                self.cut_host = int(named)
        self.cut = not self.cut

    def write_stats(self, path):
        with open(path, "w", encoding="utf-8") as out:
            out.write(f"wall_s={time.monotonic() - self.ready_at:.1f}\n")
            for h in self.hosts[1:]:
                link = self.links[h]
                out.write(f"robot{h} sent_bytes={link.bytes} received_bytes={self.received[h]} "
                          f"lost_packets={link.lost} queue_drops={link.queue_drops}\n")
            out.write(f"cut robot{self.cut_host} packets_dropped_while_cut={self.cut_packets}\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--name", required=True)
    parser.add_argument("--robots", type=int, required=True)
    parser.add_argument("--delay-ms", type=float, default=0.0)
    parser.add_argument("--loss", type=float, default=0.0)
    parser.add_argument("--rate-kbit", type=float, default=0.0)
    parser.add_argument("--queue-ms", type=float, default=500.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--stats")
    parser.add_argument("--cut-file")
    args = parser.parse_args()
    if not 1 <= args.robots <= 200 or not 0 <= args.loss < 1 or args.delay_ms < 0 or args.rate_kbit < 0 or args.queue_ms <= 0:
        print(f"link_emulator: options out of range: {vars(args)}", file=sys.stderr)
        return 2
    why = missing_feature()
    if why:
        print(f"link_emulator: skipped: {why}", file=sys.stderr)
        return SKIPPED
    stopping = []
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(1))
    signal.signal(signal.SIGINT, lambda *_: stopping.append(1))
    ap = AccessPoint(args)
    signal.signal(signal.SIGUSR1, lambda *_: ap.toggle_cut())
    if args.stats:
        signal.signal(signal.SIGUSR2, lambda *_: ap.write_stats(args.stats + ".snapshot"))
    try:
        ap.build()
        ap.ready_at = time.monotonic()
        print("ready", flush=True)
        ap.serve(lambda: bool(stopping))
    except (subprocess.CalledProcessError, OSError) as error:
        detail = error.stderr.decode().strip() if isinstance(error, subprocess.CalledProcessError) else str(error)
        print(f"link_emulator: cannot build the network: {detail}", file=sys.stderr)
        return 1
    finally:
        ap.teardown()
        if args.stats:
            ap.write_stats(args.stats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
