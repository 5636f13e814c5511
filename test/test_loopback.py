"""The network rule, read from the node's own sockets: with the loopback environment that every
process here gets (loopback.loopback_env: discovery on this host, the Fast DDS profile
config/fastdds_loopback.xml), every socket the node listens on is bound to 127.0.0.1 or ::1.

Sockets come from /proc: the node's fds that are sockets, looked up by inode in its
/proc/<pid>/net/{udp,udp6,tcp,tcp6}. What the profile cannot reach (README, "The network rule"):
the rmw, asked for LOCALHOST discovery, adds a UDP transport of its own with no interface list.
Its listening sockets lose the bind to the profile's (same ports, bound first), but its send
sockets stay: bound to an ephemeral port on 0.0.0.0 and on each other interface (the latter for
multicast, which LOCALHOST never sends). Those, and only those, may be off loopback here.
"""
from __future__ import annotations

import ipaddress
import os
from dataclasses import dataclass
from pathlib import Path

import pytest
from rosgraph_msgs.msg import Clock

from dds import REPO, start_node, stop, write_params

pytestmark = pytest.mark.dds

LOOPBACK = (ipaddress.ip_address("127.0.0.1"), ipaddress.ip_address("::1"))


@dataclass(frozen=True)
class Socket:
    kind: str  # udp, udp6, tcp, tcp6
    address: ipaddress.IPv4Address | ipaddress.IPv6Address
    port: int

    def __str__(self) -> str:
        return f"{self.kind} {self.address}:{self.port}"


def socket_inodes(pid: int) -> set[int]:
    """Inodes of the sockets among a process's open files."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:  # closed since the listing
            continue
        if target.startswith("socket:["):
            inodes.add(int(target[len("socket:["):-1]))
    return inodes


def local_address(field: str) -> tuple[ipaddress.IPv4Address | ipaddress.IPv6Address, int]:
    """A /proc/net table's local_address: hex address (32-bit words in host order) and hex port."""
    hex_ip, hex_port = field.split(":")
    raw = bytes.fromhex(hex_ip)
    raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))  # each word is little-endian
    return ipaddress.ip_address(raw), int(hex_port, 16)


def sockets(pid: int) -> list[Socket]:
    """Every UDP and TCP socket the process holds, with the address and port it is bound to."""
    inodes, found = socket_inodes(pid), []
    for kind in ("udp", "udp6", "tcp", "tcp6"):
        for line in Path(f"/proc/{pid}/net/{kind}").read_text().splitlines()[1:]:
            fields = line.split()
            if int(fields[9]) in inodes:
                found.append(Socket(kind, *local_address(fields[1])))
    return found


def ephemeral(port: int) -> bool:
    """A port the kernel picked (bind to port 0): the range it picks from."""
    low, high = map(int, Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split())
    return low <= port <= high


def off_loopback(found: list[Socket]) -> tuple[list[Socket], list[Socket]]:
    """(listening sockets off loopback, send sockets off loopback): a send socket is a UDP one on
    an ephemeral port (DDS listens on the fixed ports its domain and participant give)."""
    off = [s for s in found if s.address not in LOOPBACK]
    send = [s for s in off if s.kind.startswith("udp") and ephemeral(s.port)]
    return [s for s in off if s not in send], send


def interfaces_off_loopback() -> int:
    """How many IPv4 addresses this host has besides loopback (from /proc/net/fib_trie)."""
    lines = Path("/proc/net/fib_trie").read_text().splitlines()
    local = {lines[i - 1].split()[-1] for i, line in enumerate(lines) if "/32 host LOCAL" in line}
    return len({a for a in local if not a.startswith("127.")})


def test_the_node_listens_on_loopback_only(tmp_path, probe):
    params = write_params(tmp_path / "params.yaml", scene_file=str(REPO / "config" / "scenes" / "headland_turn.yaml"),
                          record=False, real_time_factor=1.0)
    node = start_node(params, tmp_path / "node.log")
    try:
        clock = probe.subscribe("/clock", Clock)
        assert probe.spin_until(lambda: len(clock) > 10 or node.poll() is not None, 60.0), "no /clock"
        assert node.poll() is None, (tmp_path / "node.log").read_text()
        found = sockets(node.pid)  # after discovery and data: every transport has opened its sockets
    finally:
        assert stop(node) == 0
    listening, send = off_loopback(found)
    assert [s for s in found if s not in send], "the node holds no socket on loopback: no DDS?"
    assert not listening, "listening off loopback: " + ", ".join(map(str, listening))
    # the rmw's own transport: one send socket on the any-address, one per other interface
    assert len(send) <= 1 + interfaces_off_loopback(), ", ".join(map(str, send))
