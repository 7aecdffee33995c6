"""Device profiles: the physical limits and identity of each WSG model, as data.

Every value names its source. "data sheet" values come from the vendor's published product data;
"assumed" marks values the public documents at hand do not give, chosen to be plausible and
consistent (the real gripper wins: change them here and note it in the changelog).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..protocol import DeviceType

DATA_SHEET = "data sheet"
ASSUMED = "assumed"


def encode_fw_version(major: int, minor1: int, minor2: int, rc: int = 0) -> int:
    """FW_VERSION of 50h: D15..12 major, D11..8 minor 1, D7..4 minor 2, D3..0 release candidate."""
    for name, v in (("major", major), ("minor1", minor1), ("minor2", minor2), ("rc", rc)):
        if not 0 <= v <= 15:
            raise ValueError(f"{name} {v} does not fit 4 bits")
    return (major << 12) | (minor1 << 8) | (minor2 << 4) | rc


def decode_fw_version(value: int) -> tuple[int, int, int, int]:
    """(major, minor1, minor2, rc) from FW_VERSION."""
    return (value >> 12) & 15, (value >> 8) & 15, (value >> 4) & 15, value & 15


@dataclass(frozen=True)
class Profile:
    """One gripper model.

    Units: stroke mm, speeds mm/s, accelerations mm/s², forces N (sum over both fingers, as the
    manual defines the force limit). ``sources`` maps each field name to where its value comes from.
    """

    key: str
    name: str
    device_type: DeviceType
    stroke: float
    min_speed: float
    max_speed: float
    min_acc: float
    max_acc: float
    min_force: float
    nom_force: float
    ovr_force: float
    default_acceleration: float
    homing_speed: float
    hwrev: int
    fw_version: int
    serial_number: int
    sources: dict[str, str] = field(default_factory=dict, compare=False)

    @property
    def overdrive_supported(self) -> bool:
        return self.ovr_force > self.nom_force

    def limits(self) -> dict[str, float]:
        """The 53h Get System Limits values by the catalog's field names."""
        return {
            "stroke": self.stroke, "min_speed": self.min_speed, "max_speed": self.max_speed,
            "min_acc": self.min_acc, "max_acc": self.max_acc, "min_force": self.min_force,
            "nom_force": self.nom_force, "ovr_force": self.ovr_force,
        }

    def clamp_speed(self, v: float) -> float:
        return min(max(v, self.min_speed), self.max_speed)

    def clamp_acc(self, a: float) -> float:
        return min(max(a, self.min_acc), self.max_acc)


#: mm/s² at power-up (000 §3.3.1 "On startup, a default value is used"; no manual or data sheet gives
#: it): the models' maximum, so that clients that never send 30h — the ROS driver, Stanford UMI's 30 Hz
#: PD loop — see the drive follow a speed command within one control period (docs/fidelity.md).
DEFAULT_ACCELERATION = 5000.0
DEFAULT_ACCELERATION_SOURCE = ("decided from the public clients (ROS wsg_50, UMI, minWSG never set 30h; "
                               "UMI's 30 Hz loop tracks from 3000 mm/s²), docs/fidelity.md")
_FW = encode_fw_version(4, 0, 2)  # assumed: a firmware 4.0.x, the release the newest seed documents


def _src(**given: str) -> dict[str, str]:
    names = ("stroke", "min_speed", "max_speed", "min_acc", "max_acc", "min_force", "nom_force", "ovr_force",
             "default_acceleration", "homing_speed", "hwrev", "fw_version", "serial_number")
    return {n: given.get(n, DEFAULT_ACCELERATION_SOURCE if n == "default_acceleration" else ASSUMED)
            for n in names}


PROFILES: dict[str, Profile] = {
    "wsg50": Profile(
        "wsg50", "WSG 50", DeviceType.WSG50, stroke=110.0, min_speed=5.0, max_speed=420.0, min_acc=100.0,
        max_acc=5000.0, min_force=5.0, nom_force=80.0, ovr_force=120.0, default_acceleration=DEFAULT_ACCELERATION,
        homing_speed=100.0, hwrev=1, fw_version=_FW, serial_number=10001,
        sources=_src(stroke=DATA_SHEET + " (WSG 50-110: 110 mm stroke)", max_speed=DATA_SHEET + " (420 mm/s)",
                     nom_force=DATA_SHEET + " (80 N gripping force)"),
    ),
    "wsg32": Profile(
        "wsg32", "WSG 32", DeviceType.WSG32, stroke=64.0, min_speed=5.0, max_speed=400.0, min_acc=100.0,
        max_acc=5000.0, min_force=5.0, nom_force=50.0, ovr_force=80.0, default_acceleration=DEFAULT_ACCELERATION,
        homing_speed=100.0, hwrev=1, fw_version=_FW, serial_number=20001, sources=_src(),
    ),
    "wsg25": Profile(
        "wsg25", "WSG 25", DeviceType.WSG25, stroke=64.0, min_speed=5.0, max_speed=400.0, min_acc=100.0,
        max_acc=5000.0, min_force=2.0, nom_force=20.0, ovr_force=20.0, default_acceleration=DEFAULT_ACCELERATION,
        homing_speed=100.0, hwrev=1, fw_version=_FW, serial_number=50001, sources=_src(),
    ),
    "wsg70": Profile(
        "wsg70", "WSG 70", DeviceType.WSG70, stroke=110.0, min_speed=5.0, max_speed=400.0, min_acc=100.0,
        max_acc=5000.0, min_force=20.0, nom_force=200.0, ovr_force=400.0, default_acceleration=DEFAULT_ACCELERATION,
        homing_speed=100.0, hwrev=1, fw_version=_FW, serial_number=60001,
        sources=_src(ovr_force=ASSUMED + " (above 327 N, hence the fieldbus's 1/10 N force unit on WSG 70)"),
    ),
}
"""Profiles by key. ``wsg50`` is the default model."""

DEFAULT_MODEL = "wsg50"


def get_profile(key: str) -> Profile:
    """The profile for ``key`` (``wsg50``, ``wsg32``, ``wsg25``, ``wsg70``; also ``WSG 50``, ``WSG50``)."""
    norm = key.lower().replace(" ", "").replace("-", "").replace("_", "")
    try:
        return PROFILES[norm]
    except KeyError:
        raise ValueError(f"unknown device model {key!r}; known: {', '.join(PROFILES)}") from None
