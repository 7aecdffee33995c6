"""The device description files: `wsg gsd --out DIR` and the web Help page's downloads (002 §2.1, §2.2),
and the GSDML as a controller reads it (profinet-py's parser: the AR the wire tests connect)."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

from click.testing import CliRunner

from pywsg.cli.main import cli
from pywsg.fieldbus import descriptions
from pywsg.fieldbus.profinet import ar
from pywsg.fieldbus.profinet.exchange import gsdml_path
from pywsg.fieldbus.profinet.station import DEVICE_ID, VENDOR_ID

NS = {"g": "http://www.profibus.com/GSDML/2003/11/DeviceProfile"}


def test_wsg_gsd_writes_every_description_file(tmp_path: Path) -> None:
    out = tmp_path / "gsd"
    r = CliRunner().invoke(cli, ["gsd", "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    files = json.loads(r.output)["files"]
    assert sorted(Path(f).name for f in files) == descriptions.names()
    # 002 §2.2 names the bitmap GSDML-02A2-0001-WSG.bmp; §2.1 the GSD WEIS5555.gsd (PROFIBUS drops it here)
    assert "GSDML-02A2-0001-WSG.bmp" in descriptions.names()
    assert (out / "GSDML-02A2-0001-WSG.bmp").read_bytes()[:2] == b"BM"
    for f in files:
        assert Path(f).read_bytes() == descriptions.read(Path(f).name)


def test_gsdml_declares_what_the_device_serves() -> None:
    """IDs, the 8/12-byte module, the DAP submodules and the device interval match the device's tables."""
    root = ET.parse(str(gsdml_path())).getroot()
    ident = root.find(".//g:DeviceIdentity", NS)
    assert ident is not None
    assert (int(ident.get("VendorID", ""), 16), int(ident.get("DeviceID", ""), 16)) == (VENDOR_ID, DEVICE_ID)
    dap = root.find(".//g:DeviceAccessPointItem", NS)
    assert dap is not None and int(dap.get("MinDeviceInterval", "")) == ar.MIN_DEVICE_INTERVAL
    assert int(dap.get("ModuleIdentNumber", ""), 16) == ar.DAP_MODULE
    mod = root.find(".//g:ModuleItem", NS)
    assert mod is not None and int(mod.get("ModuleIdentNumber", ""), 16) == ar.WSG_MODULE
    sub = mod.find(".//g:VirtualSubmoduleItem", NS)
    assert sub is not None and int(sub.get("SubmoduleIdentNumber", ""), 16) == ar.WSG_SUBMODULE
    sizes = {"Unsigned8": 1, "Integer16": 2, "Unsigned16": 2}

    def size(direction: str) -> int:
        items = sub.findall(f".//g:{direction}/g:DataItem", NS)   # type: ignore[union-attr]
        return sum(int(i.get("Length", "0")) or sizes[i.get("DataType", "")] for i in items)

    assert (size("Input"), size("Output")) == (ar.INPUT_LENGTH, ar.OUTPUT_LENGTH) == (12, 8)
    graphic = root.find(".//g:GraphicItem", NS)
    assert graphic is not None and graphic.get("GraphicFile", "") + ".bmp" in descriptions.names()


def test_gsdml_gives_profinet_py_the_real_configuration() -> None:
    from profinet.gsdml import load_gsdml

    slots = load_gsdml(str(gsdml_path())).build_io_slots()
    got = {(s.slot, s.subslot): (s.module_ident, s.submodule_ident, s.input_length, s.output_length) for s in slots}
    want = {(s.slot, s.subslot): (s.module_ident, s.submodule_ident, s.input_length, s.output_length) for s in ar.REAL}
    assert got == want


def test_gsdml_names_every_manufacturer_diagnosis_the_device_sends() -> None:
    """002 §3.3's error flags as PROFINET channel diagnosis: the types below 0100h are the standard's,
    the others need a ChannelDiagItem so the engineering tool can show a text."""
    from pywsg.fieldbus.profinet.alarm import ERROR_TYPES

    root = ET.parse(str(gsdml_path())).getroot()
    declared = {int(i.get("ErrorType", "")) for i in root.findall(".//g:ChannelDiagItem", NS)}
    assert {t for t in ERROR_TYPES.values() if t >= 0x100} == declared
