"""Where the PROFIBUS station address persists: ``profibus_address`` of Settings → Command Interface,
with ``profibus_address_locked``, the "no further address change" (No_Add_Chg) a Set_Slave_Address
may set.

The web page keeps its values in ``settings.interface.json`` beside the settings file
(:func:`pywsg.web.interface_page.store_path`); the slave reads its address from there at start and a
Set_Slave_Address telegram writes it back, so the address survives a restart as on a real WSG
(002 §2.1.2: "predefined to 7 … can be changed"), and so does No_Add_Chg: a slave told to accept no
further address change refuses the next Set_Slave_Address after a restart too. Without a settings
file both last until the sim stops.
No web import here: the core install has no FastAPI.
"""

from __future__ import annotations

import json
import logging
import os
import tempfile
from pathlib import Path
from typing import Any

from .diagnosis import DEFAULT_STATION_ADDRESS

log = logging.getLogger("pywsg.fieldbus.profibus")

MAX_STATION = 125


class AddressStore:
    """Read and write ``profibus_address`` in the interface settings file (None: memory only)."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self.address = DEFAULT_STATION_ADDRESS
        self.locked = False

    @classmethod
    def beside(cls, settings_path: Path | str | None) -> AddressStore:
        """``settings.json`` → ``settings.interface.json`` (the web page's file)."""
        if settings_path is None:
            return cls(None)
        p = Path(settings_path)
        return cls(p.with_name(p.stem + ".interface.json"))

    def _read(self) -> dict[str, Any]:
        if self.path is None or not self.path.exists():
            return {}
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            log.warning("PROFIBUS: cannot read %s (%s); station address %d", self.path, exc, self.address)
            return {}
        return data if isinstance(data, dict) else {}

    def load(self) -> int:
        """The stored station address, or 7 when none (or an invalid one) is stored; :attr:`locked`
        is read with it."""
        data = self._read()
        self.locked = data.get("profibus_address_locked") is True
        value = data.get("profibus_address", DEFAULT_STATION_ADDRESS)
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_STATION:
            log.warning("PROFIBUS: stored station address %r is not 0..%d; using %d", value, MAX_STATION,
                        DEFAULT_STATION_ADDRESS)
            value = DEFAULT_STATION_ADDRESS
        self.address = value
        return value

    def save(self, address: int, locked: bool = False) -> None:
        """Store ``address`` and its No_Add_Chg (atomic rewrite; the file's other fields are kept)."""
        self.address, self.locked = address, locked
        if self.path is None:
            return
        data = self._read()
        data["profibus_address"] = address
        data["profibus_address_locked"] = locked
        fd, tmp = tempfile.mkstemp(dir=self.path.parent, prefix=self.path.name, suffix=".tmp")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(json.dumps(data, indent=2) + "\n")
            os.replace(tmp, self.path)
        except OSError as exc:
            Path(tmp).unlink(missing_ok=True)
            log.warning("PROFIBUS: station address %d not saved to %s: %s", address, self.path, exc)
