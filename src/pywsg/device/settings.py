"""Settings: what the real gripper's web interface sets, persisted atomically as JSON.

Session values set by command (acceleration 30h, force limit 32h, soft limits 34h, overdrive 37h)
are not settings: they reset when the device restarts, as the manual says. The defaults they
start from are here.
"""

from __future__ import annotations

import glob
import json
import math
import os
import tempfile
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

from .profiles import PROFILES, get_profile

FINGER_TYPES = ("generic", "fmf", "dsa")
MAX_FILE_BYTES = 64 * 1024
"""A settings file is ~400 bytes; anything far larger is not one (and is not read into memory)."""


class SettingsError(ValueError):
    """A settings file could not be read or holds invalid values. The file is left untouched."""


@dataclass(frozen=True)
class Settings:
    """Device settings (web interface: Settings → Command Interface / Motion Configuration).

    - ``crc_check``: evaluate the CRC of received frames (1.4.1).
    - ``fast_stop_on_disconnect``: FAST STOP when a TCP client closes without 07h (1.4.2).
    - ``homing_direction``: default homing direction, 1 positive (opening) or 2 negative (closing).
    - ``auto_homing``: home in the default direction at power-up (fieldbus manual §5.4), so the
      gripper is referenced without a Homing command.
    - ``clamping_travel``: mm the fingers may move beyond the nominal part width while gripping.
    - ``default_acceleration``: mm/s² at startup (None: the model's default).
    - ``default_force_limit``: N at startup (None: the model's nominal force).
    - ``model``: device profile key (``wsg50``, ``wsg32``, ``wsg25``, ``wsg70``).
    - ``serial_number``: 50h SN (None: the profile's).
    - ``finger1`` / ``finger2``: installed finger type (``generic``, ``fmf``, ``dsa``).
    - ``script``: firmware plugin started at power-up (``ros_measure``, ``umi_measure``), or None.
    - ``tag``: the device tag (51h/52h; set by command, kept here so it survives a restart), or None.
    - ``location`` / ``contact``: shown in the web interface's header (fieldbus manual 003 §6,
      figure 1: "Location: n/a, Contact: n/a"), or None.
    """

    crc_check: bool = True
    fast_stop_on_disconnect: bool = True
    homing_direction: int = 1
    auto_homing: bool = False
    clamping_travel: float = 5.0
    default_acceleration: float | None = None
    default_force_limit: float | None = None
    model: str = "wsg50"
    serial_number: int | None = None
    finger1: str = "generic"
    finger2: str = "generic"
    script: str | None = None
    tag: str | None = None
    location: str | None = None
    contact: str | None = None

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise :class:`SettingsError` (a ValueError) naming the first invalid field."""
        for name in ("tag", "location", "contact"):  # 000 §3.5.2: up to 64 characters, no control characters
            text = getattr(self, name)
            if text is not None and (not isinstance(text, str) or not text or len(text) > 64
                                     or any(not " " <= c <= "~" for c in text)):
                raise SettingsError(f"{name}: must be 1 to 64 printable ASCII characters, or empty")
        for name in ("crc_check", "fast_stop_on_disconnect", "auto_homing"):
            if not isinstance(getattr(self, name), bool):
                raise SettingsError(f"{name}: must be true or false")
        if not isinstance(self.model, str) or self.model not in PROFILES:
            raise SettingsError(f"model: unknown device model {self.model!r} (known: {', '.join(PROFILES)})")
        p = get_profile(self.model)
        if isinstance(self.homing_direction, bool) or self.homing_direction not in (1, 2):
            raise SettingsError("homing_direction: must be 1 (positive) or 2 (negative)")
        if not _number(self.clamping_travel) or not 0 <= self.clamping_travel <= p.stroke:
            raise SettingsError(f"clamping_travel: must be a number of mm in 0..{p.stroke:g}")
        if self.default_acceleration is not None and (
            not _number(self.default_acceleration) or not p.min_acc <= self.default_acceleration <= p.max_acc
        ):
            raise SettingsError(f"default_acceleration: must be in {p.min_acc:g}..{p.max_acc:g} mm/s²")
        if self.default_force_limit is not None and (
            not _number(self.default_force_limit) or not p.min_force <= self.default_force_limit <= p.nom_force
        ):
            raise SettingsError(f"default_force_limit: must be in {p.min_force:g}..{p.nom_force:g} N")
        if self.serial_number is not None and (
            isinstance(self.serial_number, bool) or not isinstance(self.serial_number, int)
            or not 0 <= self.serial_number <= 0xFFFFFFFF
        ):
            raise SettingsError("serial_number: must be an integer in 0..4294967295")
        for name in ("finger1", "finger2"):
            if getattr(self, name) not in FINGER_TYPES:
                raise SettingsError(f"{name}: must be one of {', '.join(FINGER_TYPES)}")
        if self.script is not None:
            from .plugins import PLUGINS  # late: plugins import the gripper

            if self.script not in PLUGINS:
                raise SettingsError(f"script: unknown plugin {self.script!r} (known: {', '.join(PLUGINS)})")

    # --- derived values -------------------------------------------------------------------------

    @property
    def acceleration(self) -> float:
        """Startup acceleration in mm/s²."""
        return self.default_acceleration if self.default_acceleration is not None else \
            get_profile(self.model).default_acceleration

    @property
    def force_limit(self) -> float:
        """Startup force limit in N."""
        return self.default_force_limit if self.default_force_limit is not None else \
            get_profile(self.model).nom_force

    # --- persistence ----------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Settings:
        """Build from a mapping; unknown keys are an error (a typo must not pass silently)."""
        if not isinstance(data, dict):
            raise SettingsError("settings must be a JSON object")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise SettingsError(f"{unknown[0]}: unknown setting")
        values = dict(data)
        for name in ("clamping_travel", "default_acceleration", "default_force_limit"):
            if isinstance(values.get(name), int) and not isinstance(values.get(name), bool):
                values[name] = float(values[name])
        try:
            return cls(**values)
        except TypeError as exc:  # pragma: no cover - all fields have defaults
            raise SettingsError(str(exc)) from None

    def updated(self, **changes: Any) -> Settings:
        """A validated copy with ``changes`` applied."""
        return replace(self, **changes)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Settings:
        """Read settings from ``path``; a missing file gives the defaults.

        A file that cannot be read or parsed raises :class:`SettingsError`: one line naming the file
        and what to do. It is never overwritten behind the user's back. Temporary files a killed
        save left beside it are removed first (:meth:`clean_temporaries`).
        """
        p = Path(path)
        cls.clean_temporaries(p)
        fix = "fix it or move it away to start from the defaults"
        try:
            with p.open("rb") as f:
                raw = f.read(MAX_FILE_BYTES + 1)
        except FileNotFoundError:
            return cls()
        except OSError as exc:
            raise SettingsError(f"{p}: cannot read settings: {exc.strerror or exc}") from None
        if len(raw) > MAX_FILE_BYTES:
            raise SettingsError(f"{p}: not a settings file (over {MAX_FILE_BYTES // 1024} KiB); {fix}") from None
        try:
            data = json.loads(raw.decode("utf-8"))
        except UnicodeDecodeError:
            raise SettingsError(f"{p}: cannot read settings (not UTF-8 text); {fix}") from None
        except json.JSONDecodeError as exc:
            raise SettingsError(f"{p}: corrupt settings file (not JSON: {exc}); {fix}") from None
        except RecursionError:
            raise SettingsError(f"{p}: corrupt settings file (nested too deeply); {fix}") from None
        except ValueError as exc:  # e.g. an integer of more than 4300 digits
            raise SettingsError(f"{p}: corrupt settings file ({str(exc).split(';')[0]}); {fix}") from None
        try:
            return cls.from_dict(data)
        except SettingsError as exc:
            raise SettingsError(f"{p}: {exc}; {fix}") from None

    @staticmethod
    def clean_temporaries(path: str | os.PathLike[str]) -> list[Path]:
        """Remove the temporary files an interrupted :meth:`save` (SIGKILL, power loss) left beside
        ``path``; returns what was removed. The settings file itself is always whole (rename)."""
        p = Path(path)
        removed: list[Path] = []
        try:
            leftovers = list(p.parent.glob(f".{glob.escape(p.name)}.*.tmp"))
        except OSError:
            return removed
        for tmp in leftovers:
            try:
                tmp.unlink()
                removed.append(tmp)
            except OSError:
                pass
        return removed

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write atomically: a temporary file in the same directory, fsync, then rename over ``path``."""
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        data = json.dumps(self.to_dict(), indent=2, sort_keys=True) + "\n"
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, p)
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise


def _number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
