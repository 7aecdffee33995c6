"""The virtual WSG as a PROFINET IO device on one Linux network interface (asyncio).

::

    dev = await serve_profinet(gripper, "eth1", name="wsg50", controller=fieldbus_controller)
    print(dev.line())      # PROFINET eth1 station 'wsg50' MAC 02:..:..
    ...
    await dev.close()

One raw AF_PACKET socket bound to the interface (needs root or CAP_NET_RAW) carries everything: DCP,
the cyclic RT frames, and ARP/UDP for the device's own IP suite — the host's addresses and routes are
never changed (docs/fidelity.md). The 8 output bytes of each new output frame go to the same
:class:`~pywsg.fieldbus.controller.FieldbusController` the other buses use; each input frame carries
``controller.input_bytes()``.
"""

from __future__ import annotations

import asyncio
import errno
import gc
import logging
import os
import socket
import time
import uuid
from pathlib import Path
from typing import Any

from ..controller import FieldbusController
from ..image import OutputImage
from . import lldp
from .alarm import DIAGNOSIS_FLAGS, FID_ALARM_HIGH, FID_ALARM_LOW, AlarmChannel
from .ar import AR, ARState, ConnectionManager, Listener
from .cyclic import CyclicThread, attach_filter
from .dcp import IN_OPERATION, OK, DcpHandlers, DcpResponder
from .ether import ETH_P_IP, ETH_P_PNIO, IpStack, mac_text, parse_frame
from .im import Identity, IMData
from .rpc import RPC_PORT
from .rt import SUBSTITUTE, CyclicCodec, OutputConsumer
from .station import NO_IP, ORDER_ID, IpSuite, PermanentStore, Station

log = logging.getLogger(__name__)

BUS_NAME = "PROFINET IO"
ETH_P_ALL = 0x0003
PACKET_OUTGOING = 4
CCONTROL_PORT = 0xC001             # our UDP port for the ApplicationReady request (any would do)
FRAMES_PER_WAKE = 64               # bounded work per readable event: a flood cannot starve the loop
APP_READY_RETRIES, APP_READY_TIMEOUT_S = 5, 1.0
SIGNAL_S = 3.0                     # how long the "flashing" shows after a DCP Signal
#: Shortest period of the application's side of the cycle (input image, diagnosis), s: the cyclic thread
#: sends every cycle, the image it sends is at most this old.
APP_PERIOD_S = 0.002


class ProfinetError(RuntimeError):
    """The device cannot start (interface missing, no permission)."""


def interface_mac(iface: str) -> bytes:
    """The interface's MAC address (``/sys/class/net/IFACE/address``)."""
    try:
        text = Path(f"/sys/class/net/{iface}/address").read_text().strip()
    except OSError:
        raise ProfinetError(f"PROFINET: no network interface {iface!r} (see `ip link`)") from None
    return bytes.fromhex(text.replace(":", ""))


def open_raw_socket(iface: str) -> socket.socket:
    """A non-blocking raw socket receiving every frame of ``iface``."""
    try:
        sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
    except PermissionError:
        raise ProfinetError(f"PROFINET on {iface} needs root or CAP_NET_RAW for a raw socket "
                            f"(e.g. sudo setcap cap_net_raw+ep $(readlink -f $(which python3)))") from None
    try:
        sock.bind((iface, 0))
    except OSError as exc:
        sock.close()
        raise ProfinetError(f"PROFINET: cannot bind to {iface}: {exc.strerror or exc}") from None
    sock.setblocking(False)
    return sock


def interface_ipv4(iface: str) -> str | None:
    """The interface's own (primary) IPv4 address, or None (SIOCGIFADDR)."""
    import fcntl
    import struct

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            res = fcntl.ioctl(s.fileno(), 0x8915, struct.pack("256s", iface.encode()[:15]))
        except OSError:
            return None
    return socket.inet_ntoa(res[20:24])


def _identity(gripper: Any) -> Identity:
    profile = getattr(gripper, "profile", None)
    name = str(getattr(profile, "name", ORDER_ID))
    serial = str(getattr(gripper, "serial_number", "") or "")
    fw = int(getattr(profile, "fw_version", 0x4000) or 0x4000)
    return Identity(order_id=name, serial_number=serial,
                    software_revision=("V", (fw >> 12) & 15, (fw >> 8) & 15, (fw >> 4) & 15))


class ProfinetDevice:
    """PROFINET IO device of one virtual gripper (a ``BusAdapter``: ``name``, ``bus_state()``, ``close()``)."""

    name = BUS_NAME

    def __init__(self, gripper: Any, iface: str, controller: FieldbusController, *, station_name: str | None = None,
                 ip: IpSuite | None = None, store: PermanentStore | None = None) -> None:
        self.gripper = gripper
        self.iface = iface
        self.controller = controller
        self.store = store or PermanentStore(None)
        mac = interface_mac(iface)
        self.station = Station(mac=mac)
        self.station.name = station_name if station_name is not None else (self.store.name() or "")
        self.station.ip = ip or self.store.ip() or IpSuite()
        self.ipstack = IpStack(mac, self.station.ip.ip)
        self.dcp = DcpResponder(self.station, DcpHandlers(self._set_name, self._set_ip, self._signal, self._reset))
        self.cm = ConnectionManager(self.station, _identity(gripper),
                                    Listener(self._connected, self._prm_end, self._released))
        self.cm.sysstate = lambda: int.from_bytes(self.controller.input_bytes()[2:6], "little")
        # I&M1-4 as the settings file keeps them; a write stores them there again
        self.cm.im.data = IMData.load(self.store.data, save=lambda changed: self.store.save(**changed))
        self.port = self.cm.pdev.port
        self._lldp: asyncio.TimerHandle | None = None
        self.codec: CyclicCodec | None = None
        self.alarms: AlarmChannel | None = None
        self.sock: socket.socket | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._tick: asyncio.TimerHandle | None = None
        self.rt: CyclicThread | None = None   # the AR's cyclic path (its own thread and socket)
        self._app_ready: tuple[uuid.UUID, int, AR] | None = None   # activity, tries, AR
        self._app_ready_timer: asyncio.TimerHandle | None = None
        self.consumer = OutputConsumer()
        self._signal_until = 0.0
        # bus statistics (Fieldbus Monitor)
        self.frames_in = self.frames_out = self.missed = self.watchdog_expiries = 0
        self.ar_count = 0
        self.last_abort = ""
        self._last_counter: int | None = None
        self._last_frame_t = 0.0
        self._seq = 0
        self._diag_ready = False
        self._next = 0.0
        self._house: asyncio.TimerHandle | None = None

    # --- life cycle -------------------------------------------------------------------------------
    async def start(self) -> ProfinetDevice:
        self._loop = asyncio.get_running_loop()
        self.sock = open_raw_socket(self.iface)
        attach_filter(self.sock, cyclic=False)   # the cyclic frames are the cyclic thread's (cyclic.py)
        self._loop.add_reader(self.sock.fileno(), self._readable)
        self._house = self._loop.call_later(1.0, self._housekeeping)
        self._send_lldp()
        attach = getattr(self.controller, "attach_bus", None)
        if attach is not None:
            attach(self)
        self._check_conflict()
        # A full garbage collection holds the GIL, and so the cyclic thread, for as long as it walks every
        # object; what exists once the device is up lives as long as the process: freeze it, so the
        # collections that remain are short (a 1 ms cycle is shorter than a full one).
        gc.collect()
        gc.freeze()
        log.info("PROFINET: %s", self.line())
        return self

    def url(self) -> str:
        """``profinet://IFACE/STATION`` (what ``wsg plc-demo --url`` takes)."""
        return f"profinet://{self.iface}/{self.station.name}"

    def line(self) -> str:
        """The one line ``wsg sim`` prints: URL, then MAC and IP."""
        ip = self.station.ip.ip if self.station.ip.ip != NO_IP else "none yet, set by DCP"
        unnamed = "" if self.station.name else "unnamed: set the name by DCP, "
        return f"{self.url()} ({unnamed}MAC {mac_text(self.station.mac)}, IP {ip})"

    async def close(self) -> None:
        if self.cm.io_ar is not None:
            self.cm.drop(self.cm.io_ar, "device stopped")
        self._stop_rt()
        if self._tick is not None:
            self._tick.cancel()
        if self._app_ready_timer is not None:
            self._app_ready_timer.cancel()
        if self._house is not None:
            self._house.cancel()
        if self._lldp is not None:
            self._lldp.cancel()
            if self.port.lldp_send:   # TTL 0: the neighbour forgets us at once (IEEE 802.1AB shutdown)
                self._send(self._lldp_frame(ttl=0))
        if self.sock is not None:
            if self._loop is not None:
                self._loop.remove_reader(self.sock.fileno())
            self.sock.close()
            self.sock = None
        detach = getattr(self.controller, "detach_bus", None)
        if detach is not None:
            detach(self)

    def bus_state(self) -> dict[str, str]:
        """Rows for the Fieldbus Monitor's Bus State."""
        ar = self.cm.io_ar
        state = "No connection (waiting for a controller)" if ar is None else ar.state.value
        rows = {
            "Interface": self.iface,
            "Station name": self.station.name or "(none)",
            "IP address": f"{self.station.ip.ip} / {self.station.ip.mask}" if self.ipstack.has_ip else "(none)",
            "MAC address": mac_text(self.station.mac),
            "AR state": state,
        }
        if ar is not None and ar.output_cr is not None:
            rows["Controller"] = f"{ar.request.station_name} {ar.controller_ip} ({mac_text(ar.controller_mac)})"
            rows["Cycle time"] = f"{ar.output_cr.cycle_s * 1000:g} ms"
        rows["Frames in / out"] = f"{self.frames_in} / {self.frames_out}"
        if ar is not None and self.consumer.substituting:
            rows["Outputs"] = f"substitute values (zero image): {self.consumer.substituting}"
        if self.rt is not None:
            rows["Cyclic path"] = (f"input frames at most {self.rt.late_max * 1000:.1f} ms late, output frames at "
                                   f"most {self.rt.gap_max * 1000:.1f} ms apart")
        rows["Missed frames"] = str(self.missed)
        rows["Watchdog expiries"] = str(self.watchdog_expiries)
        if self.alarms is not None and self.alarms.sent:
            rows["Diagnosis alarms"] = f"{self.alarms.acked} acknowledged of {self.alarms.sent} sent"
        if self.last_abort:
            rows["Last AR end"] = self.last_abort
        if time.monotonic() < self._signal_until:
            rows["Signal"] = "flashing (DCP Signal)"
        n = self.port.current(time.monotonic())
        rows["LLDP neighbour"] = f"{n.peer_station_name} {n.peer_port_name} ({mac_text(n.mac)})" if n else "(none)"
        mismatch = self.port.mismatch(time.monotonic())
        if mismatch:
            rows["Port check"] = f"mismatch: {mismatch}"
        return rows

    # --- receive --------------------------------------------------------------------------------
    def _readable(self) -> None:
        sock = self.sock
        if sock is None:
            return
        for _ in range(FRAMES_PER_WAKE):
            try:
                data, addr = sock.recvfrom(2048)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                if exc.errno == errno.ENETDOWN:
                    return
                log.warning("PROFINET: receive on %s: %s", self.iface, exc)
                return
            if addr[2] == PACKET_OUTGOING:
                continue
            try:
                self._frame(data)
            except Exception:   # a frame must never stop the device: log it and go on
                log.exception("PROFINET: frame of %d bytes not handled", len(data))

    def _frame(self, data: bytes) -> None:
        frame = parse_frame(data)
        if frame is None:
            return
        if frame.ethertype == ETH_P_PNIO:
            if len(frame.payload) < 2:
                return
            fid = int.from_bytes(frame.payload[:2], "big")
            if 0xFEFC <= fid <= 0xFEFF:
                for delay, reply in self.dcp.handle(frame):
                    if delay and self._loop is not None:
                        self._loop.call_later(delay, self._send, reply)
                    else:
                        self._send(reply)
            elif self.codec is not None and frame.src == self.codec.ar.controller_mac:
                if fid in (FID_ALARM_LOW, FID_ALARM_HIGH):
                    if self.alarms is not None:
                        for reply in self.alarms.handle(frame.payload[2:]):
                            self._send(reply)
                elif self.rt is None:   # a device not started (tests): the loop takes the frame itself
                    self._output_frame(frame.payload)
            return
        if frame.ethertype == lldp.ETH_P_LLDP:
            if frame.dst != lldp.LLDP_MULTICAST:
                return   # LLDP goes to the nearest-bridge address only
            neighbour = lldp.parse(frame, time.monotonic())
            if neighbour is not None and neighbour != self.port.neighbour:
                if self.port.neighbour is None or (neighbour.chassis_id, neighbour.port_id) != (
                        self.port.neighbour.chassis_id, self.port.neighbour.port_id):
                    log.info("PROFINET: LLDP neighbour %s port %s (%s)", neighbour.chassis_id, neighbour.port_id,
                             mac_text(neighbour.mac))
                self.port.neighbour = neighbour
            return
        if frame.ethertype in (ETH_P_IP, 0x0806):
            replies, udp = self.ipstack.handle(frame)
            for r in replies:
                self._send(r)
            if udp is None:
                return
            if udp.dport == RPC_PORT:
                answer = self.cm.handle(udp.data, udp.src_ip, udp.sport)
                if answer is not None:
                    self._send(self.ipstack.udp(udp.src_mac, udp.src_ip, RPC_PORT, udp.sport, answer))
            elif udp.dport == CCONTROL_PORT and self._app_ready is not None:
                activity, _tries, ar = self._app_ready
                done = ConnectionManager.application_ready_done(udp.data, activity)
                if done is True and ar is self.cm.io_ar:
                    self._app_ready = None
                    ar.state = ARState.DATA
                    ar.last_activity = time.monotonic()
                    log.info("PROFINET: ApplicationReady confirmed by %s: data exchange", ar.controller_ip)
                elif done is False:
                    self._abort(ar, "the controller refused ApplicationReady")

    def _output_frame(self, payload: bytes) -> None:
        """An output frame (after the EtherType), taken and applied at once (the cyclic thread splits the two)."""
        image = self._consume(payload)
        if image is not None:
            self._apply(image)

    def _consume(self, payload: bytes) -> bytes | None:
        """Bus statistics and the consumer rule for one output frame: the image to apply, or None. Runs on the
        cyclic thread (it touches only counters and the codec, never the gripper)."""
        codec = self.codec
        if codec is None:
            return None
        out = codec.output(payload)
        if out is None:
            return None
        self.frames_in += 1
        self._last_frame_t = time.monotonic()
        if self._last_counter is not None:
            gap = (out.cycle_counter - self._last_counter) & 0xFFFF
            step = codec.out_cr.send_clock_factor * codec.out_cr.reduction_ratio
            if gap > step and step:
                self.missed += gap // step - 1
        self._last_counter = out.cycle_counter
        was = self.consumer.substituting
        image = self.consumer.take(out)
        if self.consumer.substituting != was:
            if self.consumer.substituting:
                log.warning("PROFINET: the controller's outputs are not valid (%s): substitute values, a zero "
                            "output image", self.consumer.substituting)
            else:
                log.info("PROFINET: the controller's outputs are valid again (RUN, IOPS GOOD)")
        return image

    def _apply(self, image: bytes) -> None:
        """Hand an output image to the application (on the loop)."""
        if self.codec is not None:   # not after the AR ended: its fail-safe image stands
            self.controller.write_outputs(OutputImage.unpack(image))

    def _send(self, frame: bytes) -> None:
        if self.sock is None:
            return
        try:
            self.sock.send(frame)
        except (BlockingIOError, InterruptedError):
            log.debug("PROFINET: send buffer full, frame dropped")
        except OSError as exc:
            log.warning("PROFINET: send on %s: %s", self.iface, exc.strerror or exc)

    # --- LLDP ------------------------------------------------------------------------------------------
    def _lldp_frame(self, ttl: int = lldp.TTL_S) -> bytes:
        return lldp.build(self.station.mac, self.station.name, self.ipstack.ip if self.ipstack.has_ip else NO_IP,
                          name_of_device=self.port.name_of_device, ttl=ttl)

    def _announce(self) -> None:
        """A new name or IP: the neighbour learns it now, not at the next interval."""
        if self.port.lldp_send:
            self._send(self._lldp_frame())

    def _send_lldp(self) -> None:
        """Our LLDP frame now and every TX_INTERVAL_S (not while a PeerToPeerBoundary forbids it)."""
        if self.port.lldp_send:
            self._send(self._lldp_frame())
        if self._loop is not None and self.sock is not None:
            self._lldp = self._loop.call_later(lldp.TX_INTERVAL_S, self._send_lldp)

    # --- web interface (Settings → Command Interface, 003 §3.2) ------------------------------------------
    def apply_settings(self, name: str | None = None, ip: IpSuite | None = None) -> None:
        """New NameOfStation and/or IP suite from the web interface (already stored by it). An AR in
        progress ends: its controller addressed the old station (the 003 §3.2 warning)."""
        changed = (name is not None and name != self.station.name) or (ip is not None and ip != self.station.ip)
        if not changed:
            return
        if self.cm.io_ar is not None:
            self._abort(self.cm.io_ar, "station name or IP changed in the web interface")
        if name is not None:
            self.station.name = name
        if ip is not None:
            self.station.ip = ip
            self.ipstack.ip = ip.ip
        self._announce()
        self._syslog(f"PROFINET: web interface set station '{self.station.name}', IP {self.station.ip.ip}")

    # --- DCP Set ----------------------------------------------------------------------------------
    def _check_conflict(self) -> None:
        """The host answering for the station's IP on the same wire would confuse every controller."""
        if self.ipstack.has_ip and interface_ipv4(self.iface) == self.station.ip.ip:
            log.warning("PROFINET: %s is also the host's own address on %s: give the station an address of its "
                        "own (the host answers ARP for it too)", self.station.ip.ip, self.iface)

    def _set_name(self, name: str, permanent: bool) -> int:
        if self.cm.io_ar is not None and name != self.station.name:
            log.warning("PROFINET: DCP Set NameOfStation refused: an AR is established")
            return IN_OPERATION
        self.station.name = name
        if permanent:
            self.store.save(profinet_name=name)
        self._announce()
        self._syslog(f"PROFINET: NameOfStation set to '{name}' ({'permanent' if permanent else 'temporary'})")
        return OK

    def _set_ip(self, suite: IpSuite, permanent: bool) -> int:
        if self.cm.io_ar is not None and suite != self.station.ip:
            log.warning("PROFINET: DCP Set IP refused: an AR is established")
            return IN_OPERATION
        self.station.ip = suite
        self.ipstack.ip = suite.ip
        self._check_conflict()
        self._announce()
        if permanent:
            self.store.save(ip_address=suite.ip, netmask=suite.mask,
                            gateway="" if suite.gateway == NO_IP else suite.gateway)
        self._syslog(f"PROFINET: IP suite set to {suite.ip}/{suite.mask} gateway {suite.gateway} "
                     f"({'permanent' if permanent else 'temporary'}; the host's addresses are unchanged)")
        return OK

    def _signal(self) -> None:
        self._signal_until = time.monotonic() + SIGNAL_S
        self._syslog("PROFINET: DCP Signal: the LED flashes (identify this gripper)")

    def _reset(self, mode: int) -> int:
        """ResetToFactory mode 2 (reset communication parameters): NameOfStation and IP suite, the running
        ones and the stored ones. Refused while an IO AR runs, like a Set (docs/fidelity.md "DCP during an AR")."""
        if self.cm.io_ar is not None:
            log.warning("PROFINET: DCP Reset to Factory refused: an AR is established")
            return IN_OPERATION
        self.station.name = ""
        self.station.ip = IpSuite()
        self.ipstack.ip = NO_IP
        self.store.save(profinet_name="")
        self.store.forget("ip_address", "netmask", "gateway")
        self._announce()
        self._syslog(f"PROFINET: reset to factory settings (mode {mode}, communication parameters): station name "
                     f"and IP cleared, also in the settings file")
        return OK

    def _syslog(self, text: str) -> None:
        log.info("%s", text)
        glog = getattr(self.gripper, "log", None)
        add = getattr(glog, "add", None)
        if add is not None:
            from ...device.log import LogLevel

            clock = getattr(self.gripper, "clock", time.monotonic)
            add(clock(), LogLevel.INFO, text)

    # --- AR events ----------------------------------------------------------------------------------
    def _connected(self, ar: AR) -> None:
        self.codec = CyclicCodec(ar, self.station.mac)
        self.alarms = AlarmChannel(ar, self.station.mac, self.cm.alarm_ref) if ar.alarm is not None else None
        self._diag_ready = False
        self.ar_count += 1
        self._last_counter = None
        self.consumer = OutputConsumer()
        self._last_frame_t = 0.0
        self._syslog(f"PROFINET: connected to {ar.request.station_name} at {ar.controller_ip}")
        self.cm.pdev.logbook.add(ar.uuid.bytes)
        self._stop_rt()
        if self._loop is not None and self.sock is not None:
            codec, loop = self.codec, self._loop
            assert ar.input_cr is not None
            try:
                self.rt = CyclicThread(
                    self.iface, ar.controller_mac, ar.output_frame_id, ar.input_cr.cycle_s,
                    build=codec.input_frame, consume=self._consume,
                    judge=lambda now: self._supervise(ar, codec, now), post=loop.call_soon_threadsafe,
                    apply=self._apply, expired=lambda why: self._expired(ar, why), sent=self._sent)
            except OSError as exc:
                self.rt = None
                log.warning("PROFINET: no socket for the cyclic thread (%s)", exc)
                self._abort(ar, f"cannot start the cyclic path: {exc}")
                return
            self.rt.inputs = self._input_bytes()
            self.rt.start()
            if self._tick is not None:
                self._tick.cancel()
            self._next = loop.time()
            self._tick = loop.call_at(self._next, self._cycle)

    def _prm_end(self, ar: AR) -> None:
        if self.codec is not None and ar is self.codec.ar:
            self.codec.provider_ok = True
        self._seq += 1
        self._app_ready = (uuid.uuid4(), 0, ar)
        if self._loop is not None:
            self._loop.call_soon(self._send_app_ready)

    def _send_app_ready(self) -> None:
        if self._app_ready is None:
            return
        activity, tries, ar = self._app_ready
        if ar is not self.cm.io_ar:
            self._app_ready = None
            return
        if tries >= APP_READY_RETRIES:
            self._abort(ar, "no answer to ApplicationReady")
            return
        self._app_ready = (activity, tries + 1, ar)
        mac = self.ipstack.neighbours.get(ar.controller_ip)
        if mac is None:
            self._send(self.ipstack.arp_request(ar.controller_ip))
        else:
            data = self.cm.application_ready(ar, activity, self._seq)
            self._send(self.ipstack.udp(mac, ar.controller_ip, CCONTROL_PORT, RPC_PORT, data))
        if self._loop is not None:
            self._app_ready_timer = self._loop.call_later(APP_READY_TIMEOUT_S, self._send_app_ready)

    def _released(self, ar: AR, why: str) -> None:
        if self.codec is not None and ar is self.codec.ar:
            self.codec = None
            self.alarms = None
            self._stop_rt()
            if self._tick is not None:
                self._tick.cancel()
                self._tick = None
        self.last_abort = why
        if ar.is_io:
            # LogBook: a release is no error; any other end is an abort (PNIOStatus CF 81 FD 00: "AR aborted")
            self.cm.pdev.logbook.add(ar.uuid.bytes, 0 if why == "released by the controller" else 0xCF81FD00)
            self._syslog(f"PROFINET: AR of {ar.controller_ip} ended: {why}")
            if why != "released by the controller":
                self._fail_safe(why)
            elif self.consumer.applied not in (None, SUBSTITUTE):
                # a Release is no lost master (no FAST STOP), but its outputs end with the AR: substitute
                # values, as for ProviderState STOP (a JOG level must not outlive the AR)
                self.controller.write_outputs(OutputImage.unpack(SUBSTITUTE))
            self.consumer = OutputConsumer()

    def _abort(self, ar: AR, why: str) -> None:
        self.cm.drop(ar, why)

    def _fail_safe(self, reason: str) -> None:
        fail_safe = getattr(self.controller, "fail_safe", None)
        if fail_safe is not None:
            fail_safe(BUS_NAME, reason)
        else:   # until the shared rule lands: what a lost Modbus/TCP master does (docs/fidelity.md)
            log.warning("PROFINET: controller lost (%s); no fail_safe on this FieldbusController", reason)

    # --- cyclic -----------------------------------------------------------------------------------------
    def _stop_rt(self) -> None:
        if self.rt is not None:
            self.rt.stop()
            self.rt = None

    def _sent(self) -> None:
        self.frames_out += 1

    def _expired(self, ar: AR, why: str) -> None:
        """The cyclic thread's verdict (on the loop): the AR ends."""
        if ar is self.cm.io_ar:
            self.watchdog_expiries += 1
            self._abort(ar, why)

    def _input_bytes(self) -> bytes:
        try:
            return self.controller.input_bytes()
        except Exception:
            log.exception("PROFINET: input image")
            return bytes(12)

    def _cycle(self) -> None:
        """The application's side of the cycle, on the loop: a fresh input image for the cyclic thread to
        send, and the diagnosis alarms; every cycle, at most every :data:`APP_PERIOD_S`."""
        codec, loop, rt = self.codec, self._loop, self.rt
        if codec is None or loop is None or rt is None:
            return
        inputs = self._input_bytes()
        rt.inputs = inputs
        if self.alarms is not None:
            self._diagnosis(codec.ar, inputs)
        period = max(codec.in_cr.cycle_s, APP_PERIOD_S)
        self._next += period
        t = loop.time()
        if self._next < t - period:   # fell behind (a long pause): restart the schedule, do not burst
            self._next = t + period
        self._tick = loop.call_at(self._next, self._cycle)

    def _supervise(self, ar: AR, codec: CyclicCodec, now: float) -> str:
        """Why the AR must end now ("" while it may go on). Parameterization (Connect to PrmEnd) is
        supervised by the controller's CMInitiatorActivityTimeout (ARBlockReq, factor × 100 ms) since its
        last RPC for this AR; data exchange by the data hold time once output frames flow, and until the first
        one by the activity timeout again (docs/fidelity.md "Startup supervision")."""
        activity = ar.request.timeout_factor * 0.1
        if ar.state == ARState.PARAMETERIZING and now - ar.last_activity > activity:
            return (f"no PrmEnd within the CMInitiatorActivityTimeout ({activity:g} s) after the controller's "
                    f"last request")
        if self._last_frame_t:
            out_cr = codec.out_cr
            hold = out_cr.data_hold_factor * out_cr.cycle_s
            if now - self._last_frame_t > hold:
                return (f"watchdog: no output frame for {(now - self._last_frame_t) * 1000:.0f} ms "
                        f"(data hold time {hold * 1000:g} ms)")
        elif ar.state == ARState.DATA and now - ar.last_activity > activity:
            return f"no output frame from the controller within the CMInitiatorActivityTimeout ({activity:g} s)"
        return ""

    def _diagnosis(self, ar: AR, inputs: bytes) -> None:
        """Diagnosis alarms for listed error flags rising or clearing (002 §3.3), once data exchange runs."""
        alarms = self.alarms
        assert alarms is not None
        sysstate = int.from_bytes(inputs[2:6], "little")
        if self.codec is not None:   # the next input frame's StationProblemIndicator: a diagnosis is pending
            self.codec.station_problem = bool(sysstate & DIAGNOSIS_FLAGS)
        if not self._diag_ready:
            if ar.state != ARState.DATA:
                return
            self._diag_ready = True
            # flags already set when data exchange starts are no news: the controller sees them in SYSSTATE
            alarms.active = sysstate & DIAGNOSIS_FLAGS
        alarms.flags(sysstate)
        for frame in alarms.poll():
            self._send(frame)
        if alarms.failed:
            self._abort(ar, "diagnosis alarm not acknowledged (alarm CR timeout)")

    def _housekeeping(self) -> None:
        """Once a second: end a device-access AR whose controller went quiet."""
        ar = self.cm.access_ar
        if ar is not None and time.monotonic() - ar.last_activity > max(ar.request.timeout_factor * 0.1, 1.0):
            self.cm.drop(ar, "device-access AR idle (CMInitiatorActivityTimeout)")
        if self._loop is not None and self.sock is not None:
            self._house = self._loop.call_later(1.0, self._housekeeping)


async def serve_profinet(gripper: Any, iface: str, controller: FieldbusController | None = None, *,
                         station_name: str | None = None, ip: IpSuite | None = None,
                         store_path: Path | None = None) -> ProfinetDevice:
    """Start the PROFINET IO device of ``gripper`` on ``iface`` (a controller is made if none is given)."""
    if controller is None:
        controller = FieldbusController(gripper)
    dev = ProfinetDevice(gripper, iface, controller, station_name=station_name, ip=ip,
                         store=PermanentStore(store_path))
    return await dev.start()


def has_raw_socket_permission() -> bool:
    """True when this process may open raw sockets (root or CAP_NET_RAW)."""
    try:
        socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL)).close()
    except PermissionError:
        return False
    return os.name == "posix"

