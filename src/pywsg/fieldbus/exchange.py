"""The PLC side's bus: the :class:`ImageExchange` Protocol and :func:`open_exchange` (by URL).

A master exchanges the fieldbus register image with one gripper: it writes the 8 output bytes
(002 §3.1 / 003 §4.1.1) and reads the 12 input bytes (002 §3.2 / 003 §4.1.2), in image order.
:class:`~pywsg.fieldbus.plc.AsyncFieldbusGripper` and ``wsg plc-demo`` work over any of them:

==============================================  =====================================================
URL                                             implementation
==============================================  =====================================================
``modbus-tcp://HOST[:PORT]`` (502)              :mod:`pywsg.fieldbus.modbus.exchange` (pymodbus client)
``profinet://IFACE/STATION``                    :mod:`pywsg.fieldbus.profinet.exchange`
``profibus://PORT?address=7&baudrate=19200``    :mod:`pywsg.fieldbus.profibus.exchange`
==============================================  =====================================================

Each bus's module is imported only when its scheme is used, so a bus's optional extra is needed
only by who uses that bus. Every module offers ``async def open_exchange(url: str, *, timeout: float)
-> ImageExchange``.
"""

from __future__ import annotations

import importlib
from typing import Protocol, runtime_checkable
from urllib.parse import urlsplit


class FieldbusConnectionError(ConnectionError):
    """No usable connection to the bus's slave: refused, lost, no reply within the timeout, or a bus
    this installation cannot open. Every :class:`ImageExchange` raises this (or another
    ``ConnectionError``) instead of its library's own exceptions, so callers handle one type."""


@runtime_checkable
class ImageExchange(Protocol):
    """One master's view of one gripper's fieldbus image (bytes in image order)."""

    async def read_inputs(self) -> bytes:
        """The 12 input bytes now (GSTATE, OF, SYSSTATE, WIDTH, FORCE, STATUS CODE)."""
        ...

    async def write_outputs(self, data: bytes) -> None:
        """Write the 8 output bytes (CMDFLAGS, IF, WIDTH, SPEED, FORCELIMIT)."""
        ...

    async def close(self) -> None:
        """Leave the bus (close the connection / end data exchange)."""
        ...


#: URL scheme → the subpackage of :mod:`pywsg.fieldbus` whose ``exchange`` module opens it.
SCHEMES = {"modbus-tcp": "modbus", "modbus": "modbus", "tcp": "modbus",
           "profinet": "profinet", "profibus": "profibus"}
#: The optional extra each bus's master needs (``pip install 'pywsg[EXTRA]'``); Modbus needs none.
EXTRAS = {"profinet": "profinet", "profibus": "profibus"}
URL_FORMS = "modbus-tcp://HOST[:PORT], profinet://IFACE/STATION or profibus://PORT?address=N&baudrate=B"


def scheme_of(url: str) -> str:
    """The URL's scheme, ``modbus-tcp`` for a bare ``HOST[:PORT]``; ValueError if no bus has it."""
    scheme = urlsplit(url).scheme.lower() if "://" in url else "modbus-tcp"
    if scheme not in SCHEMES:
        raise ValueError(f"{url!r}: unknown fieldbus URL scheme {scheme!r}; expected {URL_FORMS}")
    return scheme


async def open_exchange(url: str, *, timeout: float = 3.0) -> ImageExchange:
    """Open the master named by ``url`` (see the module docstring); ``timeout`` in s per exchange.

    Raises ValueError for a malformed URL or an unknown scheme, and :class:`FieldbusConnectionError`
    when the slave cannot be reached or this installation lacks the bus (its module or its optional
    extra), naming what to install.
    """
    bus = SCHEMES[scheme_of(url)]
    module_name = f"{__package__}.{bus}.exchange"
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        missing = exc.name or ""
        if module_name.startswith(missing):   # the bus's own module is not there
            raise FieldbusConnectionError(
                f"{url}: this pywsg has no {bus} master ({module_name} is missing)") from None
        extra = EXTRAS.get(bus)
        hint = f"pip install 'pywsg[{extra}]'" if extra else f"install {missing}"
        raise FieldbusConnectionError(f"{url}: the {bus} master needs {missing!r}: {hint}") from None
    opened: ImageExchange = await module.open_exchange(url, timeout=timeout)
    return opened


__all__ = ["SCHEMES", "FieldbusConnectionError", "ImageExchange", "open_exchange", "scheme_of"]
