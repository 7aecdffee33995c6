"""URL parsing and the exception hierarchy (no I/O)."""

from __future__ import annotations

import builtins
import pickle

import pytest

from pywsg.client import parse_url
from pywsg.errors import (
    AccessDeniedError,
    ConnectionLostError,
    FastStopError,
    NoPartError,
    NotReferencedError,
    RangeError,
    TimeoutError,
    WsgError,
    error_for,
)
from pywsg.protocol import Command, Status, StatusError, SystemFlag


def test_urls() -> None:
    ep = parse_url("tcp://10.0.0.5")
    assert (ep.scheme, ep.host, ep.port) == ("tcp", "10.0.0.5", 1000)
    assert parse_url("gripper.local:2000").port == 2000
    u = parse_url("udp://h?reply_port=1600")
    assert (u.port, u.reply_port) == (1500, 1600)
    assert parse_url("udp://h:1700").reply_port == 1501
    s = parse_url("serial:///dev/ttyUSB0?baudrate=9600")
    assert (s.path, s.baudrate) == ("/dev/ttyUSB0", 9600)
    assert parse_url("serial:///dev/pts/3").baudrate == 115200
    for bad in ("http://x", "tcp://", "udp://h?reply_port=x", "serial://", "tcp://h?foo=1", "tcp://h:99999"):
        with pytest.raises(ValueError):
            parse_url(bad)


def test_error_mapping_and_attributes() -> None:
    e = error_for(Status.E_ACCESS_DENIED, Command.PREPOSITION, SystemFlag.SF_FAST_STOP | SystemFlag.SF_REFERENCED)
    assert type(e) is FastStopError and isinstance(e, AccessDeniedError) and isinstance(e, StatusError)
    assert e.status_name == "E_ACCESS_DENIED" and e.meaning == "Access denied"
    assert e.command == Command.PREPOSITION and "SF_FAST_STOP" in str(e)
    assert type(error_for(Status.E_ACCESS_DENIED, Command.PREPOSITION, SystemFlag.NONE)) is AccessDeniedError
    assert type(error_for(Status.E_CMD_FAILED, Command.GRIP_PART)) is NoPartError
    assert type(error_for(Status.E_NOT_INITIALIZED, Command.HOMING)) is NotReferencedError
    assert type(error_for(Status.E_RANGE_ERROR, Command.PREPOSITION)) is RangeError
    t = error_for(Status.E_TIMEOUT, Command.HOMING)
    assert isinstance(t, TimeoutError) and isinstance(t, builtins.TimeoutError) and t.from_device
    unknown = error_for(999, 0xB0)
    assert type(unknown) is WsgError and unknown.status_name == "UNKNOWN_STATUS_999" and unknown.command == 0xB0
    c = ConnectionLostError("gone", 0x41)
    assert isinstance(c, ConnectionError) and c.status == Status.E_IO_ERROR and not c.from_device
    for exc in (e, t, c):
        back = pickle.loads(pickle.dumps(exc))
        assert type(back) is type(exc) and str(back) == str(exc)
