"""Status codes (command manual, Appendix A) and the exception that carries one."""

from __future__ import annotations

from enum import IntEnum


class Status(IntEnum):
    """The 31 status codes every reply starts with (2 bytes, little endian)."""

    E_SUCCESS = 0
    E_NOT_AVAILABLE = 1
    E_NO_SENSOR = 2
    E_NOT_INITIALIZED = 3
    E_ALREADY_RUNNING = 4
    E_FEATURE_NOT_SUPPORTED = 5
    E_INCONSISTENT_DATA = 6
    E_TIMEOUT = 7
    E_READ_ERROR = 8
    E_WRITE_ERROR = 9
    E_INSUFFICIENT_RESOURCES = 10
    E_CHECKSUM_ERROR = 11
    E_NO_PARAM_EXPECTED = 12
    E_NOT_ENOUGH_PARAMS = 13
    E_CMD_UNKNOWN = 14
    E_CMD_FORMAT_ERROR = 15
    E_ACCESS_DENIED = 16
    E_ALREADY_OPEN = 17
    E_CMD_FAILED = 18
    E_CMD_ABORTED = 19
    E_INVALID_HANDLE = 20
    E_NOT_FOUND = 21
    E_NOT_OPEN = 22
    E_IO_ERROR = 23
    E_INVALID_PARAMETER = 24
    E_INDEX_OUT_OF_BOUNDS = 25
    E_CMD_PENDING = 26
    E_OVERRUN = 27
    E_RANGE_ERROR = 28
    E_AXIS_BLOCKED = 29
    E_FILE_EXISTS = 30

    def __str__(self) -> str:  # print(status) -> E_ACCESS_DENIED, not 16 (IntEnum prints the number)
        return self.name

    def __format__(self, spec: str) -> str:
        # Python 3.10's Enum.__format__ formats str(self) once __str__ is overridden, so f"{status:d}"
        # raised ValueError there; 3.11 formats the number. A spec formats the number on every version.
        return str(self) if not spec else int.__format__(int(self), spec)

    @property
    def description(self) -> str:
        """The manual's one-line meaning of this status code."""
        return STATUS_DESCRIPTIONS[self]

    @property
    def is_error(self) -> bool:
        """True for every code but E_SUCCESS and E_CMD_PENDING."""
        return self not in (Status.E_SUCCESS, Status.E_CMD_PENDING)

    @classmethod
    def describe(cls, code: int) -> str:
        """``NAME (code): meaning`` for any 16-bit code, known or not."""
        try:
            status = cls(code)
        except ValueError:
            return f"unknown status {code}"
        return f"{status.name} ({code}): {status.description}"


STATUS_DESCRIPTIONS: dict[Status, str] = {
    Status.E_SUCCESS: "No error occurred, operation was successful",
    Status.E_NOT_AVAILABLE: "Function or data is not available",
    Status.E_NO_SENSOR: "No measurement converter is connected",
    Status.E_NOT_INITIALIZED: "Device was not initialized",
    Status.E_ALREADY_RUNNING: "The data acquisition is already running",
    Status.E_FEATURE_NOT_SUPPORTED: "The requested feature is currently not available",
    Status.E_INCONSISTENT_DATA: "One or more parameters are inconsistent",
    Status.E_TIMEOUT: "Timeout error",
    Status.E_READ_ERROR: "Error while reading data",
    Status.E_WRITE_ERROR: "Error while writing data",
    Status.E_INSUFFICIENT_RESOURCES: "No more memory available",
    Status.E_CHECKSUM_ERROR: "Checksum error",
    Status.E_NO_PARAM_EXPECTED: "A Parameter was given, but none expected",
    Status.E_NOT_ENOUGH_PARAMS: "Not enough parameters for executing the command",
    Status.E_CMD_UNKNOWN: "Unknown command",
    Status.E_CMD_FORMAT_ERROR: "Command format error",
    Status.E_ACCESS_DENIED: "Access denied",
    Status.E_ALREADY_OPEN: "Interface is already open",
    Status.E_CMD_FAILED: "Error while executing a command",
    Status.E_CMD_ABORTED: "Command execution was aborted by the user",
    Status.E_INVALID_HANDLE: "Invalid handle",
    Status.E_NOT_FOUND: "Device or file not found",
    Status.E_NOT_OPEN: "Device or file not open",
    Status.E_IO_ERROR: "Input/Output Error",
    Status.E_INVALID_PARAMETER: "Wrong parameter",
    Status.E_INDEX_OUT_OF_BOUNDS: "Index out of bounds",
    Status.E_CMD_PENDING: (
        "No error, but the command was not completed, yet. Another return message will follow "
        "including a status code, if the function was completed."
    ),
    Status.E_OVERRUN: "Data overrun",
    Status.E_RANGE_ERROR: "Range error",
    Status.E_AXIS_BLOCKED: "Axis blocked",
    Status.E_FILE_EXISTS: "File already exists",
}


class StatusError(Exception):
    """A reply carried an error status.

    ``command_id`` is the command that failed (None when unknown). Front ends subclass this
    (the driver's ``WsgError`` hierarchy); the device raises it internally to answer a frame.
    """

    def __init__(self, status: Status | int, command_id: int | None = None, detail: str = "") -> None:
        try:
            self.status: Status | int = Status(status)
        except ValueError:
            self.status = status
        self.command_id = command_id
        self.detail = detail
        super().__init__(self._message())

    def _message(self) -> str:
        text = Status.describe(int(self.status))
        if self.command_id is not None:
            text = f"command {self.command_id:02X}h: {text}"
        if self.detail:
            text = f"{text} ({self.detail})"
        return text
