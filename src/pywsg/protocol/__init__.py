"""Sans-IO core of the WSG binary protocol: CRC, frames, parser, status codes, flags, catalog."""

from .catalog import CATALOG, Command, CommandSpec, Field, Kind, Value, Values, command_name, spec_for
from .crc import crc16, crc16_bytewise
from .flags import (
    AutoUpdateFlag,
    DeviceType,
    FingerFlag,
    FingerType,
    GripperState,
    GState,
    HomingDirection,
    PrepositionFlag,
    SystemFlag,
)
from .frame import MAX_PAYLOAD, PREAMBLE, Frame, encode_frame
from .parser import (
    ChecksumMismatch,
    Event,
    FrameParser,
    FrameTooLarge,
    GarbageSkipped,
    ParseError,
    TrailingBytes,
    Truncated,
    parse_datagram,
)
from .status import Status, StatusError

__all__ = [
    "CATALOG", "MAX_PAYLOAD", "PREAMBLE", "AutoUpdateFlag", "ChecksumMismatch", "Command", "CommandSpec",
    "DeviceType", "Event", "Field", "FingerFlag", "FingerType", "Frame", "FrameParser", "FrameTooLarge",
    "GState", "GarbageSkipped", "GripperState", "HomingDirection", "Kind", "ParseError", "PrepositionFlag",
    "Status", "StatusError", "SystemFlag", "TrailingBytes", "Truncated", "Value", "Values", "command_name",
    "crc16", "crc16_bytewise", "encode_frame", "parse_datagram", "spec_for",
]
