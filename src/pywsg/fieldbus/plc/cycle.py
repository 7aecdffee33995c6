"""The manual's gripping cycle: the SCL demo of 002 Appendix D (states −1..10) ported to Python as a
sans-IO scan function, ``GrippingCycle.step(inputs, now) -> outputs``; ``wsg plc-demo`` runs it over any
bus. It reads the input bytes through :class:`WsgReceive`, the listing's ``WSG_RECEIVE`` struct mapped
as an S7 PLC maps it (``receive.STW1.IDLE``, ``receive.SYSSTATE.REFERENCED``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

from ...protocol import GState, Status
from ..image import CmdFlag, InputImage, OutputImage


@dataclass
class CycleConfig:
    """The listing's CycleConfig in bus units (1/100 mm, 1/100 mm/s, 1/100 N) and seconds."""

    prepos_width: int = 3000
    prepos_speed: int = 40000
    prepos_force: int = 8000
    grasp_width: int = 2200
    grasp_speed: int = 40000
    grasp_force: int = 5000
    holding_time: float = 1.0
    release_width: int = 3000
    release_speed: int = 40000
    release_force: int = 8000
    start_width: int = 6000
    start_speed: int = 40000
    start_force: int = 8000

STEP_TEXT = {
    -1: "error: reset all command flags, set STOP/ACK",
    0: "homing: wait for IDLE, reset STOP/ACK, set HOMING",
    1: "homing running? wait for POSITIONING, reset HOMING",
    2: "wait for IDLE and REFERENCED",
    3: "pre-position: MOVE to PreposWidth",
    4: "wait for POSITIONING, reset MOVE",
    5: "grip: GRIP at GraspWidth",
    6: "wait for GRIPPING, reset GRIP",
    7: "holding: hold for HoldingTime (release at once on NO_PART / PART_LOST)",
    8: "release: wait for RELEASING, reset RELEASE",
    9: "back to start: MOVE to StartWidth",
    10: "wait for POSITIONING, reset MOVE",
    11: "cycle finished: wait for IDLE, restart at step 3",
}

# TYPE "WSG_RECEIVE" of the listing (002 Appendix D, lines 5..65): names exactly as declared.
STW1_BOOLS = ("IDLE", "GRASPING", "NO_PART", "PART_LOST", "HOLDING", "RELEASING", "POSITIONING", "ERROR",
              "OF1", "OF2", "OF3", "OF4", "OF5", "OF6", "OF7", "OF8")

SYSSTATE_BOOLS = ("REFERENCED", "MOVING", "BLOCKED_MINUS", "BLOCKED_PLUS", "SOFT_LIMIT_MINUS", "SOFT_LIMIT_PLUS",
                  "AXIS_STOPPED", "TARGET_POS_REACHED", "OVERDRIVE_MODE", "FORCECNTL_MODE", "RES10", "RES11",
                  "FAST_STOP", "TEMP_WARNING", "TEMP_FAULT", "POWER_FAULT", "CURR_FAULT", "FINGER_FAULT",
                  "CMD_FAILURE", "SCRIPT_RUN", "SCRIPT_FAILURE", *(f"RES{n}" for n in range(21, 32)))


class SclBools:
    """An SCL ``Struct`` of ``Bool`` over a byte block, as an S7 PLC maps it: the k-th Bool is
    byte k // 8, bit k % 8. Read the members by name: ``receive.SYSSTATE.REFERENCED``."""

    def __init__(self, names: tuple[str, ...], block: bytes) -> None:
        if len(block) * 8 != len(names):
            raise ValueError(f"{len(names)} Bools need {len(names) // 8} bytes, got {len(block)}")
        self._bits = {name: bool(block[k // 8] >> (k % 8) & 1) for k, name in enumerate(names)}

    def __getattr__(self, name: str) -> bool:
        try:
            return self.__dict__["_bits"][name]  # type: ignore[no-any-return]
        except KeyError:
            raise AttributeError(name) from None

    def on(self) -> list[str]:
        """The names of the members that are true."""
        return [name for name, value in self._bits.items() if value]


@dataclass(frozen=True)
class WsgReceive:
    """``WSG_RECEIVE``: the 12 input bytes as the listing's PLC sees them (Int/UInt big-endian)."""

    STW1: SclBools
    SYSSTATE: SclBools
    WIDTH: int
    FORCE: int
    ERROR_CODE: int

    @classmethod
    def from_bytes(cls, data: bytes) -> WsgReceive:
        """Map the 12 received bytes onto the struct."""
        if len(data) != 12:
            raise ValueError(f"WSG_RECEIVE is 12 bytes, got {len(data)}")
        return cls(SclBools(STW1_BOOLS, data[0:2]), SclBools(SYSSTATE_BOOLS, data[2:6]),
                   int.from_bytes(data[6:8], "big", signed=True), int.from_bytes(data[8:10], "big"),
                   int.from_bytes(data[10:12], "big"))


@dataclass
class GrippingCycle:
    """The SCL ``GrippingCycle`` function block. Call :meth:`step` once per PLC scan.

    Ported faithfully, with two robustness changes (docs/fieldbus.md, docs/fidelity.md):

    - a step waiting for a *running* state (POSITIONING, GRIPPING, RELEASING) also accepts the
      state that follows it, because a fast virtual gripper can finish a short motion between two
      scans;
    - such a step treats a refused command (IDLE with an error STATUS CODE) like ERROR.

    ``recover_fast_stop`` (off by default, as the listing): every step that checks ``STW1.ERROR``
    (1..10 and the default) goes to step −1 on ``SYSSTATE.FAST_STOP`` too, doing nothing else in that
    scan. A FAST STOP sets the gripper state to IDLE, not ERROR (002 §4.6), so the listing taken
    literally waits for ever in a step that waits for a running state or for HOLDING (e.g. step 7
    when the FAST STOP strikes while GRIPPING); its error step −1 (STOP/ACK: "Acknowledge a FAST
    STOP") is the recovery the listing provides. Steps −1 and 0 are the listing's: while a fault
    refuses the acknowledge, −1 → 0 → 1 → −1 repeats, each time with a new STOP/ACK edge.
    :meth:`fast_stop_hint` says why a listing-exact cycle stopped making progress.

    ``state`` starts at 0 (homing); the listing's initial -2 falls into the default branch, which
    restarts at step 3 without homing.
    """

    config: CycleConfig = field(default_factory=CycleConfig)
    state: int = 0
    recover_fast_stop: bool = False
    send: OutputImage = field(default_factory=OutputImage)
    holding_active: bool = False
    timer_due: float | None = None
    cycles: int = 0
    error_count: int = 0
    holds: int = 0
    no_part: int = 0
    log: Callable[[str], None] | None = None
    # The last few transitions logged: a loop (-1 -> 0 -> 1 -> -1 while a fault refuses every
    # command) is logged once, then summed up when something else happens.
    _recent: list[str] = field(default_factory=list, repr=False)
    _repeated: int = field(default=0, repr=False)

    def _set(self, on: CmdFlag = CmdFlag.NONE, off: CmdFlag = CmdFlag.NONE, **params: int) -> None:
        self.send = replace(self.send, cmdflags=(self.send.cmdflags | on) & ~off, **params)

    def _say(self, text: str) -> None:
        if self.log is None:
            return
        if text in self._recent:
            self._repeated += 1
            return
        if self._repeated:
            self.log(f"        ... the steps above repeated ({self._repeated} more transitions)")
            self._repeated = 0
        self._recent = [*self._recent[-2:], text]
        self.log(text)

    def step(self, receive: InputImage | WsgReceive, now: float) -> OutputImage:
        """One scan: read ``receive`` (as ``WSG_RECEIVE``), run the CASE, return the outputs to write."""
        rcv = receive if isinstance(receive, WsgReceive) else WsgReceive.from_bytes(receive.pack())
        stw1, sysstate = rcv.STW1, rcv.SYSSTATE
        cfg = self.config
        timer_expired = self.timer_due is not None and now >= self.timer_due
        do_next = False
        state = self.state
        error = stw1.ERROR
        ok = rcv.ERROR_CODE == Status.E_SUCCESS
        # Port addition: a command the gripper refused leaves it IDLE with an error STATUS CODE; the
        # steps waiting for a running state treat that like ERROR instead of waiting forever.
        refused = stw1.IDLE and rcv.ERROR_CODE not in (Status.E_SUCCESS, Status.E_CMD_PENDING)

        if self.recover_fast_stop and sysstate.FAST_STOP and state > 0:
            # Option, not the listing: a FAST STOP shows IDLE, not ERROR (002 §4.6), but is an error to
            # acknowledge (App. B D12), which step -1 does. Like the listing's ERROR check, it replaces
            # the step (with ERROR none of a step's IDLE / running-state conditions can hold either).
            self.state = -1
        elif state == -1:
            self.error_count += 1
            self._set(on=CmdFlag.STOP_ACK, off=CmdFlag.FASTSTOP | CmdFlag.GRIP | CmdFlag.HOMING
                      | CmdFlag.JOG_MINUS | CmdFlag.JOG_PLUS | CmdFlag.MOVE | CmdFlag.RELEASE)
            do_next = True
        elif state == 0:
            if not stw1.IDLE:
                self.state = -1
            else:
                self._set(on=CmdFlag.HOMING, off=CmdFlag.STOP_ACK)
                do_next = True
        elif state == 1:
            if error or refused:
                self.state = -1
            # POSITIONING while homing; IDLE and REFERENCED if homing finished between two scans.
            if stw1.POSITIONING or (stw1.IDLE and ok and sysstate.REFERENCED):
                self._set(off=CmdFlag.HOMING)
                do_next = True
        elif state == 2:
            if error:
                self.state = -1
            if stw1.IDLE:
                if not sysstate.REFERENCED:
                    self.state = -1
                else:
                    do_next = True
        elif state == 3:
            if error:
                self.state = -1
            if stw1.IDLE:
                self._set(on=CmdFlag.MOVE, width=cfg.prepos_width, speed=cfg.prepos_speed,
                          force_limit=cfg.prepos_force)
                do_next = True
        elif state == 4:
            if error or refused:
                self.state = -1
            if stw1.POSITIONING or (stw1.IDLE and ok):
                self._set(off=CmdFlag.MOVE)
                do_next = True
        elif state == 5:
            if error:
                self.state = -1
            if stw1.IDLE:
                self._set(on=CmdFlag.GRIP, width=cfg.grasp_width, speed=cfg.grasp_speed,
                          force_limit=cfg.grasp_force)
                do_next = True
        elif state == 6:
            if error or refused:
                self.state = -1
            if stw1.GRASPING or stw1.HOLDING or stw1.NO_PART or stw1.PART_LOST:
                self._set(off=CmdFlag.GRIP)
                do_next = True
        elif state == 7:
            if error:
                self.state = -1
            if stw1.HOLDING and not self.holding_active:
                self.holding_active = True
                self.holds += 1
                self.timer_due = now + cfg.holding_time
                timer_expired = False
            if timer_expired or stw1.NO_PART or stw1.PART_LOST:
                if stw1.NO_PART:
                    self.no_part += 1
                self.holding_active = False
                self.timer_due = None
                self._set(on=CmdFlag.RELEASE, width=cfg.release_width, speed=cfg.release_speed,
                          force_limit=cfg.release_force)
                do_next = True
        elif state == 8:
            if error or refused:
                self.state = -1
            if stw1.RELEASING or (stw1.IDLE and ok):
                self._set(off=CmdFlag.RELEASE)
                do_next = True
        elif state == 9:
            if error:
                self.state = -1
            if stw1.IDLE:
                self._set(on=CmdFlag.MOVE, width=cfg.start_width, speed=cfg.start_speed,
                          force_limit=cfg.start_force)
                do_next = True
        elif state == 10:
            if error or refused:
                self.state = -1
            if stw1.POSITIONING or (stw1.IDLE and ok):
                self._set(off=CmdFlag.MOVE)
                do_next = True
        else:  # default: state not in -1..10
            if error:
                self.state = -1
            if stw1.IDLE:
                self.state = 3
                self.cycles += 1

        if do_next:
            self.state += 1
        if self.state != state:
            self._say(f"step {state:>2} -> {self.state:>2}: {STEP_TEXT.get(self.state, 'default branch')}"
                      f"  [{_gstate_name(stw1)}, {_status_name(rcv.ERROR_CODE)}]")
        return self.send

    def fast_stop_hint(self, receive: InputImage | WsgReceive) -> str | None:
        """Why the cycle may wait for ever: FAST STOP set while it runs the listing exactly, else None."""
        rcv = receive if isinstance(receive, WsgReceive) else WsgReceive.from_bytes(receive.pack())
        if self.recover_fast_stop or not rcv.SYSSTATE.FAST_STOP:
            return None
        return (f"step {self.state} ({STEP_TEXT.get(self.state, 'default branch')}) with FAST STOP set and gripper "
                f"state {_gstate_name(rcv.STW1)}: the listing (002 App. D) leaves a step for its error step only "
                "on ERROR, and a FAST STOP sets IDLE (002 §4.6); --recover-fast-stop treats FAST STOP like ERROR")


GSTATE_NAMES = {"GRASPING": GState.GRIPPING.name}
"""The listing's Bool names (STW1) that differ from the gripper state's name."""


def _status_name(code: int) -> str:
    try:
        return Status(code).name
    except ValueError:
        return str(code)


def _gstate_name(stw1: SclBools) -> str:
    """The gripper state named in STW1 (one-hot) by its one name: the listing's Bool GRASPING is the
    state GRIPPING (000 §3.4.2), which the step texts beside it name too."""
    states = [GSTATE_NAMES.get(name, name) for name in STW1_BOOLS[:8] if getattr(stw1, name)]
    return states[0] if len(states) == 1 else f"GSTATE={'+'.join(states) or '0'}"
