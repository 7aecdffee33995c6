"""LLDP (IEEE 802.1AB) as a PROFINET device sends and reads it (IEC 61158-6-10 §4.13, "LLDP"), sans-IO.

What the device sends on its one port every :data:`TX_INTERVAL_S` seconds to 01-80-C2-00-00-0E:

- Chassis ID, subtype 7 "locally assigned": the NameOfStation (the MAC, subtype 4, while unnamed);
- Port ID, subtype 7: ``port-001.<NameOfStation>`` (the "name of device" form a PNIO_Version V2.3
  device with ``LLDP_NoD_Supported`` uses), or ``port-001`` in the legacy form a controller may select
  with a PDInterfaceAdjust write (MultipleInterfaceMode.NameOfDevice = 0);
- TTL :data:`TTL_S` (20 s, as IEC 61158-6-10 requires);
- PROFINET org-specific TLVs (OUI 00-0E-CF): LLDP_PNIO_PORTSTATUS (subtype 2: RTClass2/RTClass3 port
  status, both "off": an RT_CLASS_1 device), LLDP_PNIO_CHASSIS_MAC (subtype 5);
- IEEE 802.3 MAC/PHY configuration/status (OUI 00-12-0F subtype 1): autonegotiation, the operational MAU
  type (100BASE-TXFD, the GSDML's MAUTypeItem 16);
- Management address (IPv4, interface index 1) once the station has an IP; End of LLDPDU.

What the neighbour sends is kept as a :class:`Neighbour` until its TTL runs out; PDPortDataReal (802Ah)
shows it as the peer (:mod:`.pdev`).
"""

from __future__ import annotations

import ipaddress
import struct
from dataclasses import dataclass

from .ether import Frame, ether

ETH_P_LLDP = 0x88CC
LLDP_MULTICAST = bytes.fromhex("0180c200000e")
TTL_S = 20
TX_INTERVAL_S = 5.0
#: Operational MAU type 100BASE-TXFD (IEC 61158-6-10 MAUType 0010h; the GSDML's MAUTypeItem Value="16").
MAU_100BASE_TXFD = 0x0010
#: ifMauAutoNegCapAdvertisedBits: 10BASE-T half/full, 100BASE-TX half/full.
AUTONEG_ADVERTISED = 0x6C00

END, CHASSIS_ID, PORT_ID, TTL, MANAGEMENT, ORG = 0, 1, 2, 3, 8, 127
CHASSIS_MAC, CHASSIS_LOCAL = 4, 7
PORT_LOCAL = 7
OUI_PNIO, OUI_8023 = b"\x00\x0e\xcf", b"\x00\x12\x0f"
PNIO_PORT_STATUS, PNIO_CHASSIS_MAC = 2, 5
IEEE_MAC_PHY = 1
#: The port's own name (IEC 61158-6-10: "port-xyz", xyz the port number).
PORT_NAME = "port-001"
MAX_LLDPDU = 1500


def tlv(kind: int, value: bytes) -> bytes:
    """One TLV: 7-bit type, 9-bit length, value."""
    return struct.pack("!H", kind << 9 | len(value)) + value


def port_id(station_name: str, name_of_device: bool = True) -> str:
    """``port-001.<name>`` (name-of-device form) or ``port-001`` (legacy form, or an unnamed station)."""
    return f"{PORT_NAME}.{station_name}" if name_of_device and station_name else PORT_NAME


def build(mac: bytes, station_name: str, ip: str = "0.0.0.0", *,   # nosec B104: PROFINET's "no IP"
          name_of_device: bool = True, ttl: int = TTL_S) -> bytes:
    """The device's LLDP frame (``ttl`` 0: the shutdown frame that withdraws it)."""
    chassis = (tlv(CHASSIS_ID, bytes([CHASSIS_LOCAL]) + station_name.encode("ascii")) if station_name
               else tlv(CHASSIS_ID, bytes([CHASSIS_MAC]) + mac))
    pdu = (chassis
           + tlv(PORT_ID, bytes([PORT_LOCAL]) + port_id(station_name, name_of_device).encode("ascii"))
           + tlv(TTL, struct.pack("!H", ttl))
           + tlv(ORG, OUI_PNIO + struct.pack("!BHH", PNIO_PORT_STATUS, 0, 0))
           + tlv(ORG, OUI_PNIO + bytes([PNIO_CHASSIS_MAC]) + mac)
           + tlv(ORG, OUI_8023 + struct.pack("!BBHH", IEEE_MAC_PHY, 0x03, AUTONEG_ADVERTISED, MAU_100BASE_TXFD)))
    addr = ipaddress.IPv4Address(ip)
    if int(addr):
        # address string length (subtype + 4), subtype 1 IPv4, address, ifIndex subtype 2, ifIndex 1, OID none
        pdu += tlv(MANAGEMENT, struct.pack("!BB", 5, 1) + addr.packed + struct.pack("!BIB", 2, 1, 0))
    pdu += tlv(END, b"")
    return ether(LLDP_MULTICAST, mac, ETH_P_LLDP, pdu)


@dataclass(frozen=True)
class Neighbour:
    """What the port's neighbour announced in its last LLDP frame."""

    mac: bytes               # source MAC of its frame (PeerMACAddress)
    chassis_id: str
    port_id: str
    ttl: int                 # seconds
    received: float          # monotonic time it came
    mau_type: int = 0        # its operational MAU type (0: not announced)
    chassis_mac: bytes = b""  # LLDP_PNIO_CHASSIS_MAC, if it sent one
    management_ip: str = ""

    @property
    def peer_port_name(self) -> str:
        """PeerPortName: the port ID's ``port-xyz`` part (IEC 61158-6-10, "name of device" form)."""
        return self.port_id.split(".", 1)[0] if self.port_id.startswith("port-") else self.port_id

    @property
    def peer_station_name(self) -> str:
        """PeerStationName: from a ``port-xyz.<name>`` port ID, else the chassis ID."""
        if self.port_id.startswith("port-") and "." in self.port_id:
            return self.port_id.split(".", 1)[1]
        return self.chassis_id

    def alive(self, now: float) -> bool:
        return now - self.received <= self.ttl


def _text(subtype: int, value: bytes) -> str:
    if subtype in (CHASSIS_MAC, 3) and len(value) == 6:   # MAC address (chassis 4 / port 3)
        return ":".join(f"{b:02x}" for b in value)
    return value.decode("ascii", errors="replace")


def parse(frame: Frame, now: float) -> Neighbour | None:
    """The neighbour an LLDP frame announces; None if it is not a well-formed LLDPDU (every length is
    checked against the frame; the three mandatory TLVs must come first, in order)."""
    data = frame.payload[:MAX_LLDPDU]
    off = 0
    seen: list[int] = []
    chassis = port = ""
    ttl: int | None = None
    mau = 0
    chassis_mac = b""
    mgmt = ""
    while off + 2 <= len(data):
        head, = struct.unpack_from("!H", data, off)
        kind, length = head >> 9, head & 0x1FF
        value = data[off + 2:off + 2 + length]
        if len(value) != length:
            return None
        off += 2 + length
        if kind == END:
            break
        seen.append(kind)
        if kind in (CHASSIS_ID, PORT_ID) and length < 2:
            return None
        if kind == CHASSIS_ID:
            chassis = _text(value[0], value[1:])
        elif kind == PORT_ID:
            port = _text(value[0], value[1:])
        elif kind == TTL and length >= 2:
            ttl = struct.unpack_from("!H", value)[0]
        elif kind == ORG and length >= 4:
            oui, sub = value[:3], value[3]
            if oui == OUI_8023 and sub == IEEE_MAC_PHY and length >= 9:
                mau = struct.unpack_from("!H", value, 7)[0]
            elif oui == OUI_PNIO and sub == PNIO_CHASSIS_MAC and length >= 10:
                chassis_mac = value[4:10]
        elif kind == MANAGEMENT and length >= 6 and value[0] == 5 and value[1] == 1:
            mgmt = str(ipaddress.IPv4Address(value[2:6]))
    if seen[:3] != [CHASSIS_ID, PORT_ID, TTL] or ttl is None:
        return None
    return Neighbour(frame.src, chassis, port, ttl, now, mau, chassis_mac, mgmt)
