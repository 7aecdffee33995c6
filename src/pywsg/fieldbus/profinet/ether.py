"""Ethernet, ARP, IPv4 and UDP for the PROFINET device, sans-IO (built on dpkt).

The virtual device keeps its own IP suite (set by DCP or the settings file) and answers ARP, ICMP
echo and UDP on it from its raw socket, so the host's own addresses are never changed
(docs/fidelity.md). Only what an IO-controller needs is here: no fragments, no options.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import dpkt

ETH_P_PNIO = 0x8892
ETH_P_IP = 0x0800
ETH_P_ARP = 0x0806
ETH_P_VLAN = 0x8100
BROADCAST = b"\xff" * 6
#: VLAN priority tag the RT frames carry: priority 6, VLAN 0 (IOCRTagHeader 0xC000).
RT_TAG = struct.pack("!HH", ETH_P_VLAN, 0xC000)


def mac_text(mac: bytes) -> str:
    """``aa:bb:cc:dd:ee:ff``."""
    return ":".join(f"{b:02x}" for b in mac)


@dataclass(frozen=True)
class Frame:
    """One received Ethernet frame: addresses, EtherType after any VLAN tags, and the payload."""

    dst: bytes
    src: bytes
    ethertype: int
    payload: bytes


def parse_frame(data: bytes) -> Frame | None:
    """Split an Ethernet frame; skips 802.1Q tags (RT frames are priority-tagged). None: too short."""
    if len(data) < 14:
        return None
    off = 12
    ethertype = int.from_bytes(data[12:14], "big")
    while ethertype == ETH_P_VLAN and len(data) >= off + 6:
        off += 4
        ethertype = int.from_bytes(data[off:off + 2], "big")
    if ethertype == ETH_P_VLAN:
        return None
    return Frame(data[0:6], data[6:12], ethertype, data[off + 2:])


def ether(dst: bytes, src: bytes, ethertype: int, payload: bytes, tag: bool = False) -> bytes:
    """An Ethernet frame (padded to the 60-byte minimum); ``tag``: with the RT priority tag."""
    frame = dst + src + (RT_TAG if tag else b"") + struct.pack("!H", ethertype) + payload
    return frame + bytes(max(0, 60 - len(frame)))


@dataclass(frozen=True)
class Udp:
    """One UDP datagram addressed to the device."""

    src_mac: bytes
    src_ip: str
    dst_ip: str
    sport: int
    dport: int
    data: bytes


def _ip_text(raw: bytes) -> str:
    return ".".join(str(b) for b in raw)


def _ip_raw(text: str) -> bytes:
    return bytes(int(p) for p in text.split("."))


class IpStack:
    """ARP, ICMP echo and UDP for one IP address on one MAC. ``ip`` empty or 0.0.0.0: no IP (silent)."""

    def __init__(self, mac: bytes, ip: str = "0.0.0.0") -> None:  # nosec B104: PROFINET's "no IP"
        self.mac = mac
        self.ip = ip
        self._ident = 0
        #: IP → MAC learned from ARP and received datagrams (for CControl and replies).
        self.neighbours: dict[str, bytes] = {}

    @property
    def has_ip(self) -> bool:
        return self.ip not in ("", "0.0.0.0")

    def handle(self, frame: Frame) -> tuple[list[bytes], Udp | None]:
        """Frames to send back (ARP reply, echo reply) and the UDP datagram for us, if any."""
        if not self.has_ip:
            return [], None
        if frame.ethertype == ETH_P_ARP:
            return self._arp(frame), None
        if frame.ethertype != ETH_P_IP or frame.dst not in (self.mac, BROADCAST):
            return [], None
        try:
            ip = dpkt.ip.IP(frame.payload)
        except (dpkt.UnpackError, struct.error):
            return [], None
        if _ip_text(ip.dst) != self.ip or ip.mf or ip.offset:
            return [], None   # not ours, or a fragment: an RPC request never needs one
        src = _ip_text(ip.src)
        self.neighbours[src] = frame.src
        if ip.p == dpkt.ip.IP_PROTO_UDP and isinstance(ip.data, dpkt.udp.UDP):
            udp = ip.data
            return [], Udp(frame.src, src, self.ip, udp.sport, udp.dport, bytes(udp.data))
        if ip.p == dpkt.ip.IP_PROTO_ICMP and isinstance(ip.data, dpkt.icmp.ICMP) \
                and ip.data.type == dpkt.icmp.ICMP_ECHO:
            reply = dpkt.icmp.ICMP(type=dpkt.icmp.ICMP_ECHOREPLY, code=0, data=ip.data.data)
            return [self._ip_frame(frame.src, src, dpkt.ip.IP_PROTO_ICMP, bytes(reply))], None
        return [], None

    def _arp(self, frame: Frame) -> list[bytes]:
        try:
            arp = dpkt.arp.ARP(frame.payload)
        except (dpkt.UnpackError, struct.error):
            return []
        if arp.op != dpkt.arp.ARP_OP_REQUEST or len(arp.tpa) != 4 or _ip_text(arp.tpa) != self.ip:
            return []
        self.neighbours[_ip_text(arp.spa)] = bytes(arp.sha)
        reply = dpkt.arp.ARP(op=dpkt.arp.ARP_OP_REPLY, sha=self.mac, spa=arp.tpa, tha=arp.sha, tpa=arp.spa)
        return [ether(bytes(arp.sha), self.mac, ETH_P_ARP, bytes(reply))]

    def udp(self, dst_mac: bytes, dst_ip: str, sport: int, dport: int, data: bytes) -> bytes:
        """A UDP datagram from our IP as an Ethernet frame."""
        u = dpkt.udp.UDP(sport=sport, dport=dport, data=data)
        u.ulen = len(u)
        return self._ip_frame(dst_mac, dst_ip, dpkt.ip.IP_PROTO_UDP, bytes(u), udp=u)

    def _ip_frame(self, dst_mac: bytes, dst_ip: str, proto: int, body: bytes,
                  udp: dpkt.udp.UDP | None = None) -> bytes:
        self._ident = (self._ident + 1) & 0xFFFF
        ip = dpkt.ip.IP(src=_ip_raw(self.ip), dst=_ip_raw(dst_ip), p=proto, ttl=64, id=self._ident,
                        df=1, data=udp if udp is not None else body)
        ip.len = 20 + len(body)
        return ether(dst_mac, self.mac, ETH_P_IP, bytes(ip))

    def arp_request(self, ip: str) -> bytes:
        """Who has ``ip``? (before the device sends CControl to a controller it has not heard from)."""
        req = dpkt.arp.ARP(op=dpkt.arp.ARP_OP_REQUEST, sha=self.mac, spa=_ip_raw(self.ip),
                           tha=bytes(6), tpa=_ip_raw(ip))
        return ether(BROADCAST, self.mac, ETH_P_ARP, bytes(req))
