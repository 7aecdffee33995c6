"""Identity and addresses of the virtual WSG as a PROFINET IO device.

Vendor and device ID come from the name of the GSDML bitmap the manual lists (002 §2.2:
``GSDML-02A2-0001-WSG.bmp``, the naming rule being ``GSDML-<VendorID>-<DeviceID>-…``): vendor 0x02A2,
device 0x0001 (docs/fidelity.md). Permanent station name and IP suite (DCP Set with the "permanent"
qualifier, or the web interface's Settings → Command Interface) are stored in the same JSON file as
the web interface's interface settings (``settings.interface.json`` beside ``--settings``).
"""

from __future__ import annotations

import ipaddress
import json
import logging
import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

VENDOR_ID = 0x02A2
DEVICE_ID = 0x0001
#: DCP TypeOfStation (DeviceVendorValue) and the GSDML's family name.
TYPE_OF_STATION = "WSG"
#: I&M0 OrderID of the default model: the model name the web interface shows ("WSG 50 Control Panel"),
#: also the GSDML's OrderNumber; another model profile reports its own name (docs/fieldbus.md).
ORDER_ID = "WSG 50"
NO_IP = "0.0.0.0"  # nosec B104: PROFINET's "no IP address"

_LABEL = re.compile(r"^[a-z0-9]([a-z0-9-]{0,61}[a-z0-9])?$")
_PORT_NAME = re.compile(r"^port-\d{3}(-\d{5})?$")


def name_error(name: str) -> str | None:
    """Why ``name`` is not a valid NameOfStation (IEC 61158-6-10: DNS-like labels), or None.
    The empty name is valid: a device not yet named."""
    if name == "":
        return None
    if len(name) > 240:
        return "at most 240 characters"
    labels = name.split(".")
    if not all(_LABEL.match(lb) for lb in labels):
        return "labels of 1..63 characters a-z, 0-9 and '-' (not first or last), separated by '.'"
    if _PORT_NAME.match(labels[0]):
        return "must not start with port-xyz (reserved)"
    if re.fullmatch(r"\d+\.\d+\.\d+\.\d+", name):
        return "must not have the form of an IP address"
    return None


def ip_suite_error(ip: str, mask: str, gateway: str) -> str | None:
    """Why an IP suite cannot be used (0.0.0.0 everywhere = no IP is fine), or None."""
    try:
        addr, net, gw = (ipaddress.IPv4Address(x) for x in (ip, mask, gateway))
    except ValueError as exc:
        return str(exc)
    if int(addr) == 0:
        return None
    try:
        network = ipaddress.IPv4Network(f"{addr}/{net}", strict=False)
    except ValueError as exc:
        return str(exc)
    edge = addr in (network.network_address, network.broadcast_address) and network.prefixlen < 31
    if addr.is_multicast or addr.is_loopback or edge:
        return f"{addr} is not a host address"
    if int(gw) and gw not in network:
        return f"gateway {gw} not in {network}"
    return None


@dataclass
class IpSuite:
    """IP address, subnet mask, default gateway (dotted quads; 0.0.0.0: none)."""

    ip: str = NO_IP
    mask: str = NO_IP
    gateway: str = NO_IP

    def raw(self) -> bytes:
        return b"".join(ipaddress.IPv4Address(x).packed for x in (self.ip, self.mask, self.gateway))

    @classmethod
    def from_raw(cls, raw: bytes) -> IpSuite:
        return cls(*(str(ipaddress.IPv4Address(raw[i:i + 4])) for i in (0, 4, 8)))


def parse_ip_suite(text: str) -> IpSuite:
    """``IP/PREFIX``, ``IP/MASK`` or ``IP/PREFIX,GATEWAY`` (e.g. ``192.168.0.20/24``); ValueError names the fault."""
    addr, _, gateway = text.partition(",")
    iface = ipaddress.IPv4Interface(addr if "/" in addr else addr + "/24")
    suite = IpSuite(str(iface.ip), str(iface.netmask), gateway.strip() or NO_IP)
    problem = ip_suite_error(suite.ip, suite.mask, suite.gateway)
    if problem is not None:
        raise ValueError(problem)
    return suite


@dataclass
class Station:
    """What DCP shows and sets. ``permanent_*`` survive a restart (the store), the rest is temporary."""

    mac: bytes
    name: str = ""
    ip: IpSuite = field(default_factory=IpSuite)
    vendor_id: int = VENDOR_ID
    device_id: int = DEVICE_ID
    type_of_station: str = TYPE_OF_STATION


class PermanentStore:
    """Permanent NameOfStation and IP suite in ``settings.interface.json`` (keys shared with the web
    interface's Command Interface page: ``profinet_name``, ``ip_address``, ``netmask``, ``gateway``).
    ``path`` None: memory only."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self.data: dict[str, Any] = {}
        if path is not None and path.exists():
            try:
                loaded = json.loads(path.read_text(encoding="utf-8"))
                if isinstance(loaded, dict):
                    self.data = loaded
            except (OSError, ValueError) as exc:
                log.warning("PROFINET: cannot read %s (%s); using defaults", path, exc)

    def name(self) -> str | None:
        value = self.data.get("profinet_name")
        return value if isinstance(value, str) and name_error(value) is None else None

    def ip(self) -> IpSuite | None:
        ip, mask, gw = (self.data.get(k) for k in ("ip_address", "netmask", "gateway"))
        if not isinstance(ip, str) or not isinstance(mask, str):
            return None
        suite = IpSuite(ip, mask, gw if isinstance(gw, str) and gw else NO_IP)
        return suite if ip_suite_error(suite.ip, suite.mask, suite.gateway) is None else None

    def forget(self, *keys: str) -> None:
        """Remove ``keys`` from the file (Reset to Factory: the permanent IP suite must not come back)."""
        self.save()
        for key in keys:
            self.data.pop(key, None)
        self._write()

    def save(self, **values: Any) -> None:
        """Merge ``values`` into the file as it is now (the web interface writes it too) and write it
        atomically (keeps keys others own)."""
        self._reload()
        self.data.update(values)
        self._write()

    def _reload(self) -> None:
        if self.path is not None and self.path.exists():
            try:
                current = json.loads(self.path.read_text(encoding="utf-8"))
                if isinstance(current, dict):
                    self.data = current
            except (OSError, ValueError):
                pass

    def _write(self) -> None:
        if self.path is None:
            return
        fd, tmp = tempfile.mkstemp(dir=self.path.parent, prefix=self.path.name, suffix=".tmp")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(json.dumps(self.data, indent=2) + "\n")
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
