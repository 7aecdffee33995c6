"""Modbus/TCP master for the fieldbus image: the :class:`~pywsg.fieldbus.exchange.ImageExchange` of
``modbus-tcp://HOST[:PORT]`` (pymodbus client; port 502 by default).

Output bytes go to holding registers 0..3, input bytes come from input registers 0..5, register k =
image byte 2k << 8 | byte 2k+1 (the register byte order decided in docs/architecture.md).
pymodbus's exceptions become :class:`~pywsg.fieldbus.exchange.FieldbusConnectionError` with one line
that says whether the link was lost or never spoke Modbus.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any, TypeVar
from urllib.parse import urlsplit

from pymodbus.client import AsyncModbusTcpClient
from pymodbus.exceptions import ModbusException

from ..exchange import FieldbusConnectionError
from ..image import INPUT_REGISTERS, OUTPUT_REGISTERS, bytes_to_registers, registers_to_bytes

T = TypeVar("T")

STANDARD_PORT = 502  # Modbus/TCP's registered port (the server's default too)



class ModbusError(Exception):
    """The server answered a request with a Modbus exception (not a connection problem)."""


def parse_url(url: str) -> tuple[str, int]:
    """``modbus-tcp://HOST[:PORT]`` (also ``modbus://``, ``tcp://`` and a bare ``HOST[:PORT]``) →
    (host, port); port 502 by default. ValueError says what is wrong."""
    parts = urlsplit(url if "://" in url else f"modbus-tcp://{url}")
    if parts.scheme not in ("modbus-tcp", "modbus", "tcp") or not parts.hostname:
        raise ValueError(f"{url!r}: expected modbus-tcp://HOST[:PORT], e.g. modbus-tcp://127.0.0.1:5020")
    try:
        port = parts.port or STANDARD_PORT
    except ValueError:
        raise ValueError(f"{url!r}: bad port") from None
    return parts.hostname, port


class ModbusExchange:
    """The image over one Modbus/TCP connection. ``device_id``: the unit id (the WSG answers any)."""

    name = "Modbus/TCP"

    def __init__(self, client: AsyncModbusTcpClient, where: str, *, device_id: int = 1,
                 timeout: float | None = None) -> None:
        self.client = client
        self.where = where            # modbus-tcp://HOST:PORT, for messages
        self.device_id = device_id
        self.timeout = timeout        # per request, s
        self._answered = False        # a request has succeeded: a later failure is a lost link

    @classmethod
    async def open(cls, host: str = "127.0.0.1", port: int = STANDARD_PORT, *, device_id: int = 1,
                   timeout: float = 3.0) -> ModbusExchange:
        """Connect to ``host:port``; raises FieldbusConnectionError when refused or unreachable."""
        client = AsyncModbusTcpClient(host, port=port, timeout=timeout, retries=0)
        where = f"modbus-tcp://{host}:{port}"
        if not await client.connect():
            client.close()
            raise FieldbusConnectionError(f"{where}: cannot connect, refused or no such host")
        return cls(client, where, device_id=device_id, timeout=timeout)

    async def _call(self, request: Callable[[], Awaitable[T]]) -> T:
        """Make and await one pymodbus request; a transport failure (raised when the request is made,
        as pymodbus does on a closed connection, or while awaiting it) becomes FieldbusConnectionError."""
        try:
            reply = await request()
        except ModbusException as exc:
            raise FieldbusConnectionError(self._explain(exc)) from exc
        self._answered = True
        return reply

    def _explain(self, exc: ModbusException) -> str:
        """One line for a pymodbus failure: lost after replies, or never a Modbus reply at all."""
        text = str(exc)
        within = f" within {self.timeout:g} s" if self.timeout is not None else ""
        if self._answered:
            reason = f"no reply{within}" if "No response" in text else "closed by the peer"
            return f"{self.where}: connection lost ({reason})"
        if "No response" in text:
            return f"{self.where}: no Modbus reply{within} (is this a Modbus/TCP server?)"
        return f"{self.where}: {text.removeprefix('Modbus Error: ')}"

    async def read_inputs(self) -> bytes:
        """Input registers 0..5 → the 12 input bytes."""
        rr: Any = await self._call(
            lambda: self.client.read_input_registers(0, count=INPUT_REGISTERS, device_id=self.device_id))
        if rr.isError():
            raise ModbusError(f"{self.where}: reading input registers failed: {rr}")
        return registers_to_bytes(list(rr.registers))

    async def read_outputs(self) -> bytes:
        """Holding registers 0..3 → the 8 output bytes the gripper holds now (so a new master starts
        from them and opening fires no edge)."""
        rr: Any = await self._call(
            lambda: self.client.read_holding_registers(0, count=OUTPUT_REGISTERS, device_id=self.device_id))
        if rr.isError():
            raise ModbusError(f"{self.where}: reading holding registers failed: {rr}")
        return registers_to_bytes(list(rr.registers))

    async def write_outputs(self, data: bytes) -> None:
        """The 8 output bytes → holding registers 0..3 (one FC16 request)."""
        if len(data) != 2 * OUTPUT_REGISTERS:
            raise ValueError(f"the output image is {2 * OUTPUT_REGISTERS} bytes, got {len(data)}")
        rr: Any = await self._call(
            lambda: self.client.write_registers(0, bytes_to_registers(data), device_id=self.device_id))
        if rr.isError():
            raise ModbusError(f"{self.where}: writing holding registers failed: {rr}")

    async def close(self) -> None:
        """Close the connection."""
        self.client.close()


async def open_exchange(url: str, *, timeout: float = 3.0) -> ModbusExchange:
    """:func:`pywsg.fieldbus.exchange.open_exchange` for ``modbus-tcp://HOST[:PORT]``."""
    host, port = parse_url(url)
    return await ModbusExchange.open(host, port, timeout=timeout)


__all__ = ["STANDARD_PORT", "ModbusError", "ModbusExchange", "open_exchange", "parse_url"]
