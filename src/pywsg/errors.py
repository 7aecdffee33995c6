"""The driver's exceptions: one hierarchy rooted at :class:`WsgError`.

Every error carries the status code (``status``), its name (``status_name``), the manual's meaning
(``meaning``), the command it belongs to (``command``, a :class:`~pywsg.protocol.Command` when the
catalog knows the ID) and the gripper's system flags when the driver could read them (``flags``).
Errors found by the driver itself (timeouts, a dropped connection, a corrupted reply) use the status
code that describes them best and have ``from_device = False``.
"""

from __future__ import annotations

import builtins

from .protocol import CATALOG, Command, Status, StatusError, SystemFlag

__all__ = [
    "AbortedError", "AccessDeniedError", "AlreadyRunningError", "AxisBlockedError", "ChecksumError",
    "CommandFailedError", "CommandFormatError", "CommandUnknownError", "ConnectionLostError",
    "FastStopError", "InvalidParameterError", "NoPartError", "NotAvailableError", "NotReferencedError",
    "ProtocolError", "RangeError", "TimeoutError", "WsgError", "error_for",
]


class WsgError(StatusError):
    """Root of every pywsg driver error.

    ``status``: :class:`Status` (or the raw int for unknown codes); ``status_name`` e.g.
    ``"E_AXIS_BLOCKED"``; ``meaning``: the manual's text for the code; ``command``: the command ID
    (a :class:`Command` when known, else an int, None when no command is concerned); ``flags``: the
    gripper's :class:`SystemFlag` when known, else None; ``detail``: what the driver adds.
    """

    def __init__(
        self,
        status: Status | int,
        command: int | None = None,
        detail: str = "",
        *,
        flags: SystemFlag | None = None,
        from_device: bool = True,
    ) -> None:
        self.flags = flags
        self.from_device = from_device
        super().__init__(status, command, detail)

    @property
    def command(self) -> Command | int | None:
        """The command concerned, as :class:`Command` if the catalog knows it."""
        if self.command_id is None:
            return None
        try:
            return Command(self.command_id)
        except ValueError:
            return self.command_id

    @property
    def status_name(self) -> str:
        return self.status.name if isinstance(self.status, Status) else f"UNKNOWN_STATUS_{int(self.status)}"

    @property
    def meaning(self) -> str:
        return self.status.description if isinstance(self.status, Status) else "unknown status code"

    def _message(self) -> str:
        text = f"{self.status_name} ({int(self.status)}): {self.meaning}"
        cid = self.command_id
        if cid is not None:
            spec = CATALOG.get(cid)
            text = f"{spec.label if spec else f'command {cid:02X}h'}: {text}"
        if self.detail:
            text = f"{text} - {self.detail}"
        if self.flags:
            text = f"{text} [flags: {', '.join(self.flags.names())}]"
        return text

    def __reduce__(self) -> tuple[object, ...]:  # picklable across processes
        return (_rebuild, (type(self), int(self.status), self.command_id, self.detail,
                           None if self.flags is None else int(self.flags), self.from_device))


def _rebuild(cls: type[WsgError], status: int, cid: int | None, detail: str, flags: int | None,
             from_device: bool) -> WsgError:
    return cls(status, cid, detail, flags=None if flags is None else SystemFlag(flags), from_device=from_device)


class NotReferencedError(WsgError):
    """E_NOT_INITIALIZED: the gripper is not referenced. Call ``home()`` first."""


class AccessDeniedError(WsgError):
    """E_ACCESS_DENIED: the gripper refused the command (another client, disconnect announced, ...)."""


class FastStopError(AccessDeniedError):
    """E_ACCESS_DENIED while SF_FAST_STOP is set: acknowledge the FAST STOP (``acknowledge()``) first."""


class AlreadyRunningError(WsgError):
    """E_ALREADY_RUNNING: another motion is running; ``stop()`` it or wait for it."""


class AxisBlockedError(WsgError):
    """E_AXIS_BLOCKED: the fingers were blocked before reaching the target."""


class CommandFailedError(WsgError):
    """E_CMD_FAILED: the command could not be executed."""


class NoPartError(CommandFailedError):
    """E_CMD_FAILED on Grip Part: no part was found within the clamping travel (state NO_PART)."""


class AbortedError(WsgError):
    """E_CMD_ABORTED: the motion was ended by Stop or FAST STOP."""


class RangeError(WsgError):
    """E_RANGE_ERROR: the target violates the soft limits (or the stroke)."""


class ChecksumError(WsgError):
    """E_CHECKSUM_ERROR: the gripper rejected our frame's CRC, or a reply arrived with a bad CRC."""


class CommandUnknownError(WsgError):
    """E_CMD_UNKNOWN: the gripper does not know this command ID (e.g. a script command with no script)."""


class CommandFormatError(WsgError):
    """E_CMD_FORMAT_ERROR / E_NO_PARAM_EXPECTED / E_NOT_ENOUGH_PARAMS: malformed request."""


class InvalidParameterError(WsgError):
    """E_INVALID_PARAMETER: a parameter is out of its allowed set."""


class NotAvailableError(WsgError):
    """E_NOT_AVAILABLE: the function or data is not available."""


class ProtocolError(WsgError):
    """The gripper sent something the driver cannot decode (wrong reply length, bad CRC, ...)."""


class ConnectionLostError(WsgError, ConnectionError):
    """The connection dropped or could not be made; pending calls fail with this at once."""

    def __init__(self, detail: str = "connection lost", command: int | None = None, *,
                 flags: SystemFlag | None = None, from_device: bool = False) -> None:
        super().__init__(Status.E_IO_ERROR, command, detail, flags=flags, from_device=from_device)

    def __reduce__(self) -> tuple[object, ...]:
        return (type(self), (self.detail, self.command_id))


class TimeoutError(WsgError, builtins.TimeoutError):
    """No reply in time (from the driver), or E_TIMEOUT from the gripper (``from_device``)."""


class BadChecksumReply(ChecksumError, ProtocolError):
    """A frame from the gripper failed its CRC check; it was not accepted."""


#: The driver's advice, in Python words; front ends translate it (`wsg` says "run `wsg ack` first").
HINT_ACKNOWLEDGE = "call acknowledge() first"
HINT_ACKNOWLEDGE_AFTER = "then call acknowledge()"
HINT_HOME = "call home() first"

_BY_STATUS: dict[int, type[WsgError]] = {
    Status.E_NOT_INITIALIZED: NotReferencedError,
    Status.E_ACCESS_DENIED: AccessDeniedError,
    Status.E_ALREADY_RUNNING: AlreadyRunningError,
    Status.E_AXIS_BLOCKED: AxisBlockedError,
    Status.E_CMD_FAILED: CommandFailedError,
    Status.E_CMD_ABORTED: AbortedError,
    Status.E_RANGE_ERROR: RangeError,
    Status.E_CHECKSUM_ERROR: ChecksumError,
    Status.E_CMD_UNKNOWN: CommandUnknownError,
    Status.E_CMD_FORMAT_ERROR: CommandFormatError,
    Status.E_NO_PARAM_EXPECTED: CommandFormatError,
    Status.E_NOT_ENOUGH_PARAMS: CommandFormatError,
    Status.E_INVALID_PARAMETER: InvalidParameterError,
    Status.E_NOT_AVAILABLE: NotAvailableError,
    Status.E_TIMEOUT: TimeoutError,
}


# Faults that make the gripper refuse 24h while they persist (000 §3.2.5: acknowledge "after fixing
# the corresponding error cause"), named in the error instead of "acknowledge first".
_ACK_BLOCKERS = (
    (SystemFlag.SF_POWER_FAULT, "a power fault (SF_POWER_FAULT: supply voltage out of range)"),
    (SystemFlag.SF_CURR_FAULT, "a motor current fault (SF_CURR_FAULT)"),
)


def _blockers(flags: SystemFlag | None) -> list[str]:
    return [text for flag, text in _ACK_BLOCKERS if flags is not None and flags & flag]


def _ack_refused(flags: SystemFlag | None) -> str:
    found = _blockers(flags)
    if not found:
        return "acknowledge refused: the fault that caused the FAST STOP persists; fix its cause first"
    return f"acknowledge refused while {' and '.join(found)} persists; fix its cause, then acknowledge"


def error_for(status: Status | int, command: int | None, flags: SystemFlag | None = None,
              detail: str = "") -> WsgError:
    """The most specific exception for a status the gripper answered to ``command``."""
    cls = _BY_STATUS.get(int(status), WsgError)
    if cls is AccessDeniedError and command == Command.ACK_FAST_STOP:
        if flags is not None and flags & SystemFlag.SF_FAST_STOP:
            cls = FastStopError
        detail = detail or _ack_refused(flags)
    elif cls is AccessDeniedError and flags is not None and flags & SystemFlag.SF_FAST_STOP:
        cls = FastStopError
        blockers = _blockers(flags)
        if blockers:  # acknowledging is refused while the fault persists: name it first (000 §3.2.5)
            detail = detail or (f"the gripper is in FAST STOP while {' and '.join(blockers)} persists: fix its "
                                f"cause first (acknowledge is refused until then), {HINT_ACKNOWLEDGE_AFTER}")
        else:
            detail = detail or f"the gripper is in FAST STOP; {HINT_ACKNOWLEDGE}"
    elif cls is CommandFailedError and command == Command.GRIP_PART:
        cls = NoPartError
        detail = detail or "no part found within the clamping travel"
    elif cls is NotReferencedError:
        detail = detail or f"the gripper is not referenced; {HINT_HOME}"
    return cls(status, command, detail, flags=flags)
