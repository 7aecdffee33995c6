"""The fieldbus register image, sans-IO (fieldbus manual 002 §3, 003 §4).

The PLC writes an 8-byte *output* image and reads a 12-byte *input* image:

======  ===============  =============================================================
bytes   output (PLC→WSG)  input (WSG→PLC)
======  ===============  =============================================================
0       CMDFLAGS          GSTATE (one-hot gripper state)
1       IF (user flags)   OF (user flags)
2..3    WIDTH  int16      SYSSTATE 32 flag bits (bytes 2..5, see below)
4..5    SPEED  uint16
6..7    FORCELIMIT int16  WIDTH  int16
8..9                      FORCE  int16
10..11                    STATUS CODE uint16
======  ===============  =============================================================

Units on the bus: WIDTH 1/100 mm, SPEED 1/100 mm/s, FORCE and FORCELIMIT 1/100 N (1/10 N on the
WSG 70). The numeric fields are big-endian (S7 ``Int``/``UInt``) and Modbus register k is
``byte[2k] << 8 | byte[2k+1]`` (the manual's worked example, holding register 0 = 288 → MOVE + IF6,
decides it; docs/fieldbus.md). The ``*_mm`` / ``*_n`` helpers convert to mm, mm/s and N.

SYSSTATE is not a number on the bus but 32 flags: the SCL receive structure of 002 Appendix D lays
``SYSSTATE : Struct REFERENCED : Bool; MOVING : Bool; …`` over bytes 2..5, and an S7 PLC puts the
n-th Bool of a struct at byte n // 8, bit n % 8 ("the natural order of the bits, starting with Byte
0 and Bit 0", 002 §2.3). So flag bit n (Appendix B numbering) is image byte 2 + n // 8, bit n % 8:
REFERENCED is byte 2 bit 0, FAST_STOP byte 3 bit 4 — the bytes of the flag word least significant
first. Discrete input i is image byte i // 8, bit i % 8, the same rule for every input bit.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, replace

from ..protocol import GripperState, GState, Status, SystemFlag
from ..protocol.flags import NamedFlag

OUTPUT_SIZE = 8
INPUT_SIZE = 12
OUTPUT_REGISTERS = 4
INPUT_REGISTERS = 6
COILS = 16
DISCRETE_INPUTS = 48

_OUT = struct.Struct(">BBhHh")
# SYSSTATE as "<I": flag bit n lands in byte 2 + n // 8, bit n % 8 (the SCL struct of 002 App. D).
_IN = struct.Struct(">BB4shhH")
SYSSTATE_OFFSET = 2
SYSSTATE_SIZE = 4


def sysstate_bytes(flags: SystemFlag | int) -> bytes:
    """The 4 SYSSTATE bytes of the image (and of the PROFIBUS diagnosis): bit n → byte n // 8, bit n % 8."""
    return (int(flags) & 0xFFFFFFFF).to_bytes(SYSSTATE_SIZE, "little")


def sysstate_from_bytes(data: bytes) -> SystemFlag:
    """Inverse of :func:`sysstate_bytes`."""
    if len(data) != SYSSTATE_SIZE:
        raise ValueError(f"SYSSTATE is {SYSSTATE_SIZE} bytes, got {len(data)}")
    return SystemFlag(int.from_bytes(data, "little"))

INT16_MIN, INT16_MAX = -0x8000, 0x7FFF
UINT16_MAX = 0xFFFF


class CmdFlag(NamedFlag):
    """CMDFLAGS, output byte 0. Commands fire on a 0→1 edge; JOG+ / JOG- are levels.

    Prints its names (``MOVE``, ``GRIP|FASTSTOP``, ``NONE``), like the other flag types.
    """

    NONE = 0
    MOVE = 1 << 0
    GRIP = 1 << 1
    RELEASE = 1 << 2
    HOMING = 1 << 3
    STOP_ACK = 1 << 4
    FASTSTOP = 1 << 5
    JOG_PLUS = 1 << 6
    JOG_MINUS = 1 << 7


#: The edge-triggered commands (everything but the jog levels).
EDGE_COMMANDS = (CmdFlag.MOVE | CmdFlag.GRIP | CmdFlag.RELEASE | CmdFlag.HOMING
                 | CmdFlag.STOP_ACK | CmdFlag.FASTSTOP)
#: Commands that move the fingers; disabled while STOP/ACK or FASTSTOP is held at 1.
MOTION_COMMANDS = CmdFlag.MOVE | CmdFlag.GRIP | CmdFlag.RELEASE | CmdFlag.HOMING
JOG = CmdFlag.JOG_PLUS | CmdFlag.JOG_MINUS


def force_scale(model: str) -> int:
    """Bus counts per newton: 100 (1/100 N), but 10 (1/10 N) on the WSG 70 (002 §3.1, FORCELIMIT)."""
    return 10 if model.lower().replace(" ", "").replace("-", "").replace("_", "") == "wsg70" else 100


def _int16(value: float, scale: int, what: str) -> int:
    raw = round(value * scale)
    if not INT16_MIN <= raw <= INT16_MAX:
        raise ValueError(f"{what} {value} does not fit the register (int16 in 1/{scale} units)")
    return raw


def _sat16(value: float, scale: int) -> int:
    """Device side: saturate instead of failing (the real gripper cannot report beyond int16 either)."""
    return max(INT16_MIN, min(INT16_MAX, round(value * scale)))


@dataclass(frozen=True)
class OutputImage:
    """PLC → gripper, in bus units (raw register values). See the module table."""

    cmdflags: CmdFlag = CmdFlag.NONE
    if_flags: int = 0
    width: int = 0          # 1/100 mm, int16
    speed: int = 0          # 1/100 mm/s, uint16
    force_limit: int = 0    # 1/100 N (1/10 N on WSG 70), int16

    def __post_init__(self) -> None:
        if not 0 <= int(self.cmdflags) <= 0xFF or not 0 <= self.if_flags <= 0xFF:
            raise ValueError("CMDFLAGS and IF are one byte each")
        if not INT16_MIN <= self.width <= INT16_MAX or not INT16_MIN <= self.force_limit <= INT16_MAX:
            raise ValueError("WIDTH and FORCELIMIT are int16")
        if not 0 <= self.speed <= UINT16_MAX:
            raise ValueError("SPEED is uint16")

    # --- bytes and Modbus views ---------------------------------------------------------------
    def pack(self) -> bytes:
        """The 8 output bytes."""
        return _OUT.pack(int(self.cmdflags), self.if_flags, self.width, self.speed, self.force_limit)

    @classmethod
    def unpack(cls, data: bytes) -> OutputImage:
        """Parse 8 output bytes."""
        if len(data) != OUTPUT_SIZE:
            raise ValueError(f"output image is {OUTPUT_SIZE} bytes, got {len(data)}")
        cmd, if_flags, width, speed, force = _OUT.unpack(data)
        return cls(CmdFlag(cmd), if_flags, width, speed, force)

    def registers(self) -> list[int]:
        """Holding registers 0..3."""
        return bytes_to_registers(self.pack())

    @classmethod
    def from_registers(cls, regs: list[int]) -> OutputImage:
        """From holding registers 0..3."""
        return cls.unpack(registers_to_bytes(regs))

    def coils(self) -> list[bool]:
        """Coils 0..15: CMDFLAGS bits 0..7, then IF1..IF8."""
        return bits_of(int(self.cmdflags), 8) + bits_of(self.if_flags, 8)

    def with_coils(self, start: int, values: list[bool]) -> OutputImage:
        """The image after writing ``values`` to coils ``start..`` (raises IndexError beyond 15)."""
        bits = self.coils()
        if start < 0 or start + len(values) > COILS:
            raise IndexError("coils are 0..15")
        bits[start:start + len(values)] = values
        return replace(self, cmdflags=CmdFlag(int_of(bits[:8])), if_flags=int_of(bits[8:]))

    # --- units ---------------------------------------------------------------------------------
    @classmethod
    def from_units(cls, cmdflags: CmdFlag = CmdFlag.NONE, *, width_mm: float = 0.0, speed_mm_s: float = 0.0,
                   force_n: float = 0.0, if_flags: int = 0, model: str = "wsg50") -> OutputImage:
        """Build from mm, mm/s and N; raises ValueError if a value does not fit its register."""
        speed = round(speed_mm_s * 100)
        if not 0 <= speed <= UINT16_MAX:
            raise ValueError(f"speed {speed_mm_s} mm/s does not fit the register (uint16 in 1/100 mm/s)")
        return cls(cmdflags, if_flags, _int16(width_mm, 100, "width"), speed,
                   _int16(force_n, force_scale(model), "force"))

    @property
    def width_mm(self) -> float:
        """WIDTH in mm."""
        return self.width / 100

    @property
    def speed_mm_s(self) -> float:
        """SPEED in mm/s."""
        return self.speed / 100

    def force_n(self, model: str = "wsg50") -> float:
        """FORCELIMIT in N (1/10 N units on the WSG 70)."""
        return self.force_limit / force_scale(model)


@dataclass(frozen=True)
class InputImage:
    """Gripper → PLC, in bus units. See the module table."""

    gstate: GState = GState.IDLE
    of_flags: int = 0
    sysstate: SystemFlag = SystemFlag.NONE
    width: int = 0          # 1/100 mm, int16
    force: int = 0          # 1/100 N (1/10 N on WSG 70), int16
    status: int = int(Status.E_SUCCESS)

    def pack(self) -> bytes:
        """The 12 input bytes."""
        return _IN.pack(int(self.gstate), self.of_flags, sysstate_bytes(self.sysstate), self.width,
                        self.force, self.status)

    @classmethod
    def unpack(cls, data: bytes) -> InputImage:
        """Parse 12 input bytes."""
        if len(data) != INPUT_SIZE:
            raise ValueError(f"input image is {INPUT_SIZE} bytes, got {len(data)}")
        gs, of_flags, sysstate, width, force, status = _IN.unpack(data)
        return cls(GState(gs), of_flags, sysstate_from_bytes(sysstate), width, force, status)

    def registers(self) -> list[int]:
        """Input registers 0..5."""
        return bytes_to_registers(self.pack())

    @classmethod
    def from_registers(cls, regs: list[int]) -> InputImage:
        """From input registers 0..5."""
        return cls.unpack(registers_to_bytes(regs))

    def discrete_inputs(self) -> list[bool]:
        """Discrete inputs 0..47: input i is image byte i // 8, bit i % 8 (002 §2.3).

        So 0..7 are GSTATE, 8..15 OF1..OF8, 16 + n SYSSTATE flag bit n (16 = REFERENCED,
        28 = FAST_STOP), the same bits the image bytes and input registers 1..2 carry.
        """
        return image_bits(self.pack()[:DISCRETE_INPUTS // 8])

    @classmethod
    def from_state(cls, state: GripperState, sysstate: SystemFlag, width_mm: float, force_n: float,
                   status: int, of_flags: int = 0, model: str = "wsg50") -> InputImage:
        """Build from the device's state in mm and N (saturating to int16)."""
        return cls(GState.from_state(state), of_flags & 0xFF, sysstate, _sat16(width_mm, 100),
                   _sat16(force_n, force_scale(model)), int(status) & 0xFFFF)

    @property
    def state(self) -> GripperState | None:
        """The gripper state if exactly one GSTATE bit is set."""
        value = int(self.gstate)
        if value and value & (value - 1) == 0:
            return GripperState(value.bit_length() - 1)
        return None

    @property
    def width_mm(self) -> float:
        """Current opening width in mm."""
        return self.width / 100

    def force_n(self, model: str = "wsg50") -> float:
        """Current gripping force in N."""
        return self.force / force_scale(model)

    @property
    def status_code(self) -> Status | int:
        """STATUS CODE as a :class:`Status` where known."""
        try:
            return Status(self.status)
        except ValueError:
            return self.status


def bytes_to_registers(data: bytes) -> list[int]:
    """Register k = byte 2k << 8 | byte 2k+1 (image bytes in wire order)."""
    return [data[i] << 8 | data[i + 1] for i in range(0, len(data), 2)]


def registers_to_bytes(regs: list[int]) -> bytes:
    """Inverse of :func:`bytes_to_registers`."""
    return b"".join((r & 0xFFFF).to_bytes(2, "big") for r in regs)


def image_bits(data: bytes) -> list[bool]:
    """The bits of ``data`` in the natural order: bit i is byte i // 8, bit i % 8 (002 §2.3)."""
    return [bool(data[i // 8] >> (i % 8) & 1) for i in range(8 * len(data))]


def bits_of(value: int, n: int) -> list[bool]:
    """Bits 0..n-1 of ``value``, lowest first."""
    return [bool(value >> i & 1) for i in range(n)]


def int_of(bits: list[bool]) -> int:
    """Inverse of :func:`bits_of`."""
    return sum(1 << i for i, b in enumerate(bits) if b)
