"""Settings → Command Interface as on the real panel (000 §1.1, §1.4; 002 §2.1.2, §2.2.2, §2.3.2).

The real page chooses the interface the gripper listens on and configures the fieldbus (PROFIBUS
station address, predefined 7; PROFINET device name) and the IP settings. The virtual gripper
cannot apply them: ``wsg sim`` serves every interface it was started with and binds to the host's
addresses. So these values are **stored and shown, not applied**; every field says so beside it.
The PROFIBUS station address is what the Fieldbus Monitor shows as its Station Address.

Storage: the device's ``Settings`` refuse keys they do not know, so these values live in a file
of their own next to the settings file (``settings.json`` → ``settings.interface.json``), written
atomically; without a settings file they last until the simulator stops (the page says so).
The CRC and FAST-STOP-on-disconnect check boxes on the same page are real device settings
(``/api/settings``, group "interface").
"""

from __future__ import annotations

import dataclasses
import ipaddress
import json
import logging
import os
import tempfile
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, Response

from ..fieldbus.profibus import DEFAULT_STATION_ADDRESS
from ..fieldbus.profinet.station import name_error as profinet_name_error
from .context import WebContext, error

log = logging.getLogger(__name__)

INTERFACES: dict[str, str] = {
    "tcp": "Ethernet TCP/IP", "udp": "Ethernet UDP/IP", "can": "CAN bus", "serial": "RS-232 serial",
    "modbus_tcp": "Modbus/TCP (fieldbus)", "profibus": "PROFIBUS DP (fieldbus)", "profinet": "PROFINET IO (fieldbus)",
}
MAX_STATION = 125  # PROFIBUS DP: 0..125 are station addresses (126 commissioning, 127 broadcast)

# beside each field: why the virtual gripper stores it but cannot apply it
NOT_APPLIED: dict[str, str] = {
    "interface": "Stored, not applied: the simulator serves every interface it was started with "
                 "(see Serving now); a real WSG listens on the chosen one.",
    "profibus_address": "Stored, not applied: there is no PROFIBUS hardware. Shown as the Station Address "
                        "on the Fieldbus Monitor.",
    "profinet_name": "Stored, not applied: this simulator serves no PROFINET device now (wsg sim --profinet "
                     "IFACE starts one, which takes the stored name).",
    "dhcp": "Stored, not applied: the simulator keeps the host's addresses (wsg sim --host).",
    "ip_address": "Stored, not applied: the simulator keeps the host's addresses (wsg sim --host).",
    "netmask": "Stored, not applied.",
    "gateway": "Stored, not applied.",
}


@dataclasses.dataclass(frozen=True)
class InterfaceConfig:
    """What the real Command Interface page stores. Defaults: the delivery state (000 §1.1, 002 §2.1.2)."""

    interface: str = "tcp"
    profibus_address: int = DEFAULT_STATION_ADDRESS
    profinet_name: str = ""  # empty: not yet named (an engineering tool assigns it)
    dhcp: bool = False
    ip_address: str = "192.168.1.20"
    netmask: str = "255.255.255.0"
    gateway: str = ""  # empty: none


def validate(values: dict[str, Any]) -> dict[str, str]:
    """Errors by field name (empty: valid). ``values``: every field of :class:`InterfaceConfig`."""
    errors: dict[str, str] = {}
    if values["interface"] not in INTERFACES:
        errors["interface"] = f"one of {', '.join(INTERFACES)}"
    addr = values["profibus_address"]
    if isinstance(addr, bool) or not isinstance(addr, int) or not 0 <= addr <= MAX_STATION:
        errors["profibus_address"] = f"an integer in 0..{MAX_STATION}"
    name = values["profinet_name"]
    msg = profinet_name_error(name) if isinstance(name, str) else "a text"
    if msg:
        errors["profinet_name"] = msg
    if not isinstance(values["dhcp"], bool):
        errors["dhcp"] = "true or false"
    net: ipaddress.IPv4Network | None = None
    try:
        net = ipaddress.IPv4Network(f"0.0.0.0/{values['netmask']}")
        if net.prefixlen in (0, 32):
            raise ValueError
    except (ValueError, TypeError):
        errors["netmask"] = "a subnet mask such as 255.255.255.0"
        net = None
    try:
        ip = ipaddress.IPv4Address(values["ip_address"])
        host_net = ipaddress.IPv4Network(f"{ip}/{net.prefixlen}", strict=False) if net else None
        if ip.is_multicast or ip.is_unspecified or ip.is_loopback or (
                host_net is not None and ip in (host_net.network_address, host_net.broadcast_address)):
            errors["ip_address"] = "a host address (not 0.0.0.0, loopback, multicast, network or broadcast)"
    except (ValueError, TypeError):
        errors["ip_address"] = "an IPv4 address such as 192.168.1.20"
    gw = values["gateway"]
    if gw != "" and "ip_address" not in errors and net is not None:
        try:
            gateway = ipaddress.IPv4Address(gw)
            if gateway not in ipaddress.IPv4Network(f"{values['ip_address']}/{net.prefixlen}", strict=False):
                errors["gateway"] = "must be in the gripper's subnet (or empty: none)"
        except (ValueError, TypeError):
            errors["gateway"] = "an IPv4 address, or empty: none"
    return errors


class InterfaceStore:
    """The stored :class:`InterfaceConfig`: a JSON file (atomic writes) or, without one, memory."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self.config = InterfaceConfig()
        self.problem: str | None = None  # why the file could not be read (defaults in use)
        if path is not None and path.exists():
            try:
                data = json.loads(path.read_text(encoding="utf-8"))
                merged = {**dataclasses.asdict(self.config), **{k: v for k, v in data.items()
                                                                 if k in InterfaceConfig.__dataclass_fields__}}
                if validate(merged):
                    raise ValueError(f"invalid values: {validate(merged)}")
                self.config = InterfaceConfig(**merged)
            except (OSError, ValueError, AttributeError) as exc:
                self.problem = f"could not read {path}: {exc}; showing the defaults"
                log.warning("web: %s", self.problem)

    def update(self, changes: dict[str, Any]) -> dict[str, str]:
        """Apply ``changes`` (validated as a whole); errors by field, nothing stored on error."""
        unknown = {k: "unknown field" for k in changes if k not in InterfaceConfig.__dataclass_fields__}
        if unknown:
            return unknown
        merged = {**dataclasses.asdict(self.config), **changes}
        errors = validate(merged)
        if errors:
            return {k: v for k, v in errors.items() if k in changes} or errors
        new = InterfaceConfig(**merged)
        if self.path is not None:   # keys this page does not own (the PROFINET device's I&M data) stay
            _write_atomic(self.path, json.dumps({**_others(self.path), **dataclasses.asdict(new)}, indent=2) + "\n")
        self.config = new
        self.problem = None
        return {}


def _others(path: Path) -> dict[str, Any]:
    """The keys of the file as it is now that are not :class:`InterfaceConfig` fields."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return {k: v for k, v in data.items() if k not in InterfaceConfig.__dataclass_fields__} \
        if isinstance(data, dict) else {}


def _write_atomic(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def store_path(settings_path: Path | None) -> Path | None:
    """``settings.json`` → ``settings.interface.json`` beside it; None without a settings file."""
    return None if settings_path is None else settings_path.with_name(settings_path.stem + ".interface.json")


#: Beside the station address while ``wsg sim --profibus`` runs a DP slave for this gripper.
PROFIBUS_APPLIED = ("Applied at once to the running PROFIBUS DP slave and stored; a master exchanging data "
                    "with the old address loses the gripper (fail-safe). Shown as the Station Address on the "
                    "Fieldbus Monitor.")


PROFINET_APPLIED = {
    "profinet_name": "Applied at once to the running PROFINET IO device and stored; a controller's AR with the "
                     "old name ends. A controller may also set it by DCP (then shown here).",
    "ip_address": "Applied at once to the running PROFINET IO device (its own address on the --profinet "
                  "interface; the host's addresses are unchanged) and stored; an AR in progress ends.",
    "netmask": "Applied to the PROFINET IO device with the IP address.",
    "gateway": "Applied to the PROFINET IO device with the IP address.",
}


def profinet_bus(fieldbus: Any) -> Any:
    """The running PROFINET IO device of this gripper (``wsg sim --profinet IFACE``), or None."""
    controller = getattr(fieldbus, "controller", fieldbus)
    for bus in getattr(controller, "buses", ()) or ():
        if getattr(bus, "name", "") == "PROFINET IO" and hasattr(bus, "apply_settings"):
            return bus
    return None


def profibus_bus(fieldbus: Any) -> Any:
    """The running PROFIBUS DP slave of this gripper (``wsg sim --profibus``), or None."""
    controller = getattr(fieldbus, "controller", fieldbus)
    for bus in getattr(controller, "buses", ()) or ():
        if getattr(bus, "name", "") == "PROFIBUS DP" and hasattr(bus, "set_address"):
            return bus
    return None


def router(ctx: WebContext) -> APIRouter:
    """``GET`` and ``POST /api/interface`` (the panel of ``templates/interface_panels.html``)."""
    r = APIRouter()
    store = InterfaceStore(store_path(ctx.settings_path))

    def sync_profibus() -> Any:
        """The live slave's address wins over the stored one (a master may have set it: Set_Slave_Address)."""
        bus = profibus_bus(ctx.fieldbus)
        if bus is not None and store.config.profibus_address != bus.address:
            store.config = dataclasses.replace(store.config, profibus_address=bus.address)
        return bus

    def sync_profinet() -> Any:
        """The live device's name wins over the stored one (a controller may have set it by DCP)."""
        bus = profinet_bus(ctx.fieldbus)
        if bus is not None and store.config.profinet_name != bus.station.name \
                and profinet_name_error(bus.station.name) is None:
            store.config = dataclasses.replace(store.config, profinet_name=bus.station.name)
        return bus

    def view() -> dict[str, Any]:
        notes = dict(NOT_APPLIED)
        if sync_profibus() is not None:
            notes["profibus_address"] = PROFIBUS_APPLIED
        if sync_profinet() is not None:
            notes.update(PROFINET_APPLIED)
        return {"values": dataclasses.asdict(store.config), "interfaces": INTERFACES, "notes": notes,
                "max_station_address": MAX_STATION,
                "stored_in": str(store.path) if store.path else None, "problem": store.problem,
                "serving": ctx.sim_info}

    @r.get("/api/interface")
    async def get_interface() -> dict[str, Any]:
        """Stored interface settings (not applied by a virtual gripper: ``notes``)."""
        return view()

    @r.post("/api/interface")
    async def post_interface(request: Request) -> Response:
        """Change some: a JSON object {name: value}. 422 names each refused field; nothing stored then."""
        try:
            raw = json.loads(await request.body())
        except (ValueError, UnicodeDecodeError):
            return error(422, "invalid input: body is not JSON", {"_": "body is not JSON"})
        if not isinstance(raw, dict) or not raw:
            return error(422, "invalid input: expected a JSON object {name: value}", {"_": "expected a JSON object"})
        bus = sync_profibus()
        pn = sync_profinet()
        try:
            errors = store.update(raw)
        except OSError as exc:
            return error(500, f"not saved to {store.path}: {exc}")
        if errors:
            return error(422, "invalid input: " + "; ".join(f"{k}: {v}" for k, v in errors.items()), errors)
        if bus is not None and "profibus_address" in raw:
            bus.set_address(store.config.profibus_address)
        if pn is not None and raw.keys() & {"profinet_name", "ip_address", "netmask", "gateway"}:
            from ..fieldbus.profinet.station import NO_IP, IpSuite

            cfg = store.config
            suite = IpSuite(cfg.ip_address, cfg.netmask, cfg.gateway or NO_IP) \
                if raw.keys() & {"ip_address", "netmask", "gateway"} else None
            pn.apply_settings(cfg.profinet_name if "profinet_name" in raw else None, suite)
        body = view()
        body["changed"] = sorted(raw)
        return JSONResponse(body)

    return r
