"""The cyclic path of one IO AR on a thread and a raw socket of its own (IEC 61158-6-10 RT_CLASS_1).

The asyncio loop serves DCP, RPC, alarms, the web interface and every other bus of the process; a slow
moment there (a web client, a TCP flood, a Modbus master) must not delay an input frame or make the
device's watchdog miss an output frame. So one thread per AR does only this: it sends the input frame on
the cycle's schedule, takes the controller's output frames as they come, judges the data hold time, and
hands the loop what the application must act on (a changed output image, the AR's end) through
``call_soon_threadsafe``. The loop, at its own pace, refreshes the input image the thread sends.

The thread's socket is bound to EtherType 8892h with a socket filter that lets only cyclic frame IDs
(8000h–FBFFh) through; the loop's socket gets the complement (:data:`NOT_CYCLIC`), so neither sees the
other's traffic. When the process runs with SCHED_FIFO (``chrt -f``), the thread runs one priority above
it, so the cycle preempts the rest of the process.
"""

from __future__ import annotations

import logging
import os
import select
import socket
import struct
import sys
import threading
import time
from collections.abc import Callable

from .ether import ETH_P_PNIO, ETH_P_VLAN

log = logging.getLogger(__name__)

SO_ATTACH_FILTER = 26
FRAMES_PER_WAKE = 64
#: The GIL is handed over at most this often (s) while a cyclic thread runs (Python's default: 5 ms, longer
#: than a cycle).
SWITCH_INTERVAL_S = 0.0005

# classic BPF: ldh [k]; jeq/jge #k; ret #k
_LDH, _JEQ, _JGE, _RET = 0x28, 0x15, 0x35, 0x06


def _bpf(prog: list[tuple[int, int, int, int]]) -> bytes:
    return b"".join(struct.pack("HBBI", *ins) for ins in prog)


def _prog(cyclic: bool) -> bytes:
    """The filter program: accept (cyclic frames) or (everything but cyclic frames)."""
    take, drop = (0xFFFF, 0) if cyclic else (0, 0xFFFF)
    return _bpf([
        (_LDH, 0, 0, 12),                 # 0: EtherType
        (_JEQ, 4, 0, ETH_P_VLAN),         # 1: tagged → 6
        (_JEQ, 0, 8, ETH_P_PNIO),         # 2: not PNIO → 11 (not cyclic)
        (_LDH, 0, 0, 14),                 # 3: FrameID
        (_JGE, 0, 6, 0x8000),             # 4: < 8000h → 11
        (_JGE, 5, 4, 0xFC00),             # 5: ≥ FC00h → 11, else → 10 (cyclic)
        (_LDH, 0, 0, 16),                 # 6: inner EtherType
        (_JEQ, 0, 3, ETH_P_PNIO),         # 7: not PNIO → 11
        (_LDH, 0, 0, 18),                 # 8: FrameID
        (_JGE, 0, 1, 0x8000),             # 9: < 8000h → 11, else → 10
        (_JGE, 0, 1, 0xFC00),             # 10: the cyclic check for the tagged path: < FC00h → 12
        (_RET, 0, 0, drop),               # 11: not cyclic
        (_RET, 0, 0, take),               # 12: cyclic
    ])


def attach_filter(sock: socket.socket, cyclic: bool) -> bool:
    """Attach the cyclic-frame filter (``cyclic``: only them; else all but them). False: not possible here."""
    import ctypes

    prog = _prog(cyclic)
    buf = ctypes.create_string_buffer(prog)
    fprog = struct.pack("HL", len(prog) // 8, ctypes.addressof(buf))
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER, fprog)
    except OSError as exc:
        log.warning("PROFINET: no socket filter (%s): every frame goes through Python", exc)
        return False
    return True


class CyclicThread:
    """Input frames out, output frames in, for one AR. ``inputs``: the 12 bytes to send (the loop keeps it
    fresh). ``build(inputs)`` makes the next input frame; ``consume(payload)`` takes an output frame's payload
    (after the EtherType) and returns the image the application must apply, or None; ``judge(now)`` says why
    the AR must end ("" if not). ``apply(image)`` and ``expired(why)`` run on ``loop``."""

    def __init__(self, iface: str, controller_mac: bytes, frame_id: int, cycle_s: float, *,
                 build: Callable[[bytes], bytes], consume: Callable[[bytes], bytes | None],
                 judge: Callable[[float], str], post: Callable[..., object], apply: Callable[[bytes], None],
                 expired: Callable[[str], None], sent: Callable[[], None]) -> None:
        self.iface, self.controller_mac, self.frame_id, self.cycle_s = iface, controller_mac, frame_id, cycle_s
        self.build, self.consume, self.judge = build, consume, judge
        self.post, self.apply, self.expired, self.sent = post, apply, expired, sent
        self.inputs = bytes(12)
        self._stop = threading.Event()
        self.sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_PNIO))
        try:
            self.sock.bind((iface, ETH_P_PNIO))
            attach_filter(self.sock, cyclic=True)
            self.sock.setblocking(False)
        except OSError:
            self.sock.close()
            raise
        self.late_max = 0.0   # the latest an input frame left after its due time once output frames flow, s
        self.gap_max = 0.0    # the longest time between two output frames taken, s
        self.unsent = 0       # input frames the socket refused (send buffer full)
        self._last_rx = 0.0
        self._thread = threading.Thread(target=self._run, name=f"profinet-cyclic-{iface}", daemon=True)

    def start(self) -> None:
        if sys.getswitchinterval() > SWITCH_INTERVAL_S:
            sys.setswitchinterval(SWITCH_INTERVAL_S)
        self._thread.start()

    def stop(self) -> None:
        """Stop the thread and close its socket (waits for it unless called from it)."""
        log.info("PROFINET: cyclic path on %s: input frames at most %.2f ms late, output frames at most %.2f ms "
                 "apart, %d not sent (send buffer full)", self.iface, self.late_max * 1000, self.gap_max * 1000,
                 self.unsent)
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)
        self.sock.close()

    @staticmethod
    def _raise_priority() -> None:
        """One SCHED_FIFO priority above the process when it runs real time; nothing otherwise."""
        try:
            if os.sched_getscheduler(0) != os.SCHED_FIFO:
                return
            prio = min(os.sched_getparam(0).sched_priority + 1, os.sched_get_priority_max(os.SCHED_FIFO))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
        except (OSError, AttributeError) as exc:
            log.debug("PROFINET: cyclic thread keeps its priority (%s)", exc)

    def _run(self) -> None:
        self._raise_priority()
        fd = self.sock.fileno()
        cycle = self.cycle_s
        due = time.monotonic()
        try:
            while not self._stop.is_set():
                now = time.monotonic()
                if now >= due:
                    self._drain()   # frames that arrived meanwhile count before the watchdog judges
                    why = self.judge(time.monotonic())
                    if why:
                        self.post(self.expired, why)
                        return
                    if self._last_rx:   # data exchange runs (start-up is the loop's busiest moment: not counted)
                        self.late_max = max(self.late_max, now - due)
                    try:
                        self.sock.send(self.build(self.inputs))
                        self.sent()
                    except (BlockingIOError, InterruptedError):
                        self.unsent += 1
                    due += cycle
                    if due < now - cycle:   # fell behind (the machine stalled): restart the schedule, no burst
                        due = now + cycle
                    continue
                readable, _, _ = select.select([fd], [], [], due - now)
                if readable:
                    self._drain()
        except OSError as exc:
            if not self._stop.is_set():
                log.warning("PROFINET: cyclic thread on %s: %s", self.iface, exc)
        except RuntimeError:   # the loop closed under us: the process is ending
            pass

    def _drain(self) -> None:
        for _ in range(FRAMES_PER_WAKE):
            try:
                data = self.sock.recv(2048)
            except (BlockingIOError, InterruptedError):
                return
            if len(data) < 16 or data[6:12] != self.controller_mac:
                continue
            off = 16 if data[12:14] == b"\x81\x00" else 12
            if int.from_bytes(data[off + 2:off + 4], "big") != self.frame_id:
                continue
            now = time.monotonic()
            if self._last_rx:
                self.gap_max = max(self.gap_max, now - self._last_rx)
            self._last_rx = now
            image = self.consume(data[off + 2:])
            if image is not None:
                self.post(self.apply, image)
