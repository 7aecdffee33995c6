"""The device description files: `wsg gsd --out DIR` and the web Help page's downloads (003 §2.1, §3.1:
the files and the manual's ZIP packages), the GSDML as a controller reads it (profinet-py's parser: the AR
the wire tests connect) and the GSDML rules a checker applies at PNIO_Version V2.31 (docs/fieldbus.md,
"The GSDML": each ``test_gsdml_rule_N`` checks rule N there)."""

from __future__ import annotations

import io
import json
import re
import struct
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from click.testing import CliRunner

from pywsg.cli.main import cli
from pywsg.device.profiles import PROFILES
from pywsg.fieldbus import descriptions
from pywsg.fieldbus.descriptions import bitmaps
from pywsg.fieldbus.profinet import ar, im, lldp
from pywsg.fieldbus.profinet.exchange import gsdml_path
from pywsg.fieldbus.profinet.station import DEVICE_ID, ORDER_ID, VENDOR_ID, name_error

NS = {"g": "http://www.profibus.com/GSDML/2003/11/DeviceProfile"}


def test_wsg_gsd_writes_every_description_file_and_both_packages(tmp_path: Path) -> None:
    out = tmp_path / "gsd"
    r = CliRunner().invoke(cli, ["gsd", "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    files = json.loads(r.output)["files"]
    assert [Path(f).name for f in files] == descriptions.downloads() == [*descriptions.PACKAGES,
                                                                          *descriptions.names()]
    # 003 §3.1 names the GSDML (with the space) and the bitmap GSDML-02A2-0001-WSG.bmp
    assert "GSDML-V2.31-Weiss Robotics-WSG-20140401.gsdml" in descriptions.names()
    assert (out / "GSDML-02A2-0001-WSG.bmp").read_bytes()[:2] == b"BM"
    for f in files:
        assert Path(f).read_bytes() == descriptions.read(Path(f).name)
    assert not any(n.endswith(".py") for n in descriptions.names())


def test_the_zip_packages_hold_what_the_manual_lists(tmp_path: Path) -> None:
    """003 §2.1: WEIS5555.gsd, WSG_D.bmp, WSG_R.bmp, WSG_S.bmp, install.txt; §3.1: the GSDML and its bitmap."""
    want = {"WEIS5555.zip": ["WEIS5555.gsd", "WSG_D.bmp", "WSG_R.bmp", "WSG_S.bmp", "install.txt"],
            "GSDML-V2.31-Weiss Robotics-WSG-20140401.zip": ["GSDML-V2.31-Weiss Robotics-WSG-20140401.gsdml",
                                                            "GSDML-02A2-0001-WSG.bmp"]}
    for name, members in want.items():
        data = descriptions.read(name)
        assert data == descriptions.package(name)   # the same bytes every time (fixed member dates)
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            assert z.namelist() == members and z.testzip() is None
            z.extractall(tmp_path / name)
            for m in members:
                assert z.read(m) == descriptions.read(m)
    notes = descriptions.read("install.txt").decode("ascii")
    assert "WEIS5555.gsd" in notes and "Options -> Install general station description file (GSD)" in notes


def test_profibus_bitmaps_are_70_by_40_16_colour_bmps_drawn_by_the_code() -> None:
    """The GSD convention for Bitmap_Device / Bitmap_Diag / Bitmap_SF: Windows BMP, 70 x 40, 16 colours;
    the package's files are exactly what :mod:`bitmaps` draws."""
    icons = bitmaps.icons()
    assert sorted(icons) == ["WSG_D.bmp", "WSG_R.bmp", "WSG_S.bmp"]
    for name, data in icons.items():
        assert descriptions.read(name) == data
        magic, size, _r1, _r2, offset = struct.unpack_from("<2sIHHI", data)
        hsize, width, height, planes, bpp, compression, _isize, _xr, _yr, colours, _imp = struct.unpack_from(
            "<IiiHHIIiiII", data, 14)
        assert (magic, size, hsize, width, height, planes, bpp, compression, colours) == (
            b"BM", len(data), 40, 70, 40, 1, 4, 0, 16)
        assert offset == 14 + 40 + 16 * 4 and len(data) == offset + 36 * 40
    assert len(set(icons.values())) == 3   # three different pictures


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


# --- the GSDML rules of docs/fieldbus.md ("The GSDML"), one test each --------------------------------
def _root() -> ET.Element:
    return ET.parse(str(gsdml_path())).getroot()


def _one(path: str) -> ET.Element:
    found = _root().find(path, NS)
    assert found is not None, path
    return found


def _dap() -> ET.Element:
    return _one(".//g:DeviceAccessPointItem")


def test_gsdml_rule_1_file_name_and_schema_version() -> None:
    """GSDML-V<schema>-<vendor>-<family>-<date>, as 003 §3.1 spells it; the schema, the XSD it names and the
    DAP's PNIO_Version agree."""
    name = Path(str(gsdml_path())).name
    assert name == "GSDML-V2.31-Weiss Robotics-WSG-20140401.gsdml"
    m = re.fullmatch(r"GSDML-(V\d+\.\d+)-([^-]+)-([^-]+)-(\d{8})\.gsdml", name)
    assert m is not None
    root = _root()
    xsd = root.get("{http://www.w3.org/2001/XMLSchema-instance}schemaLocation", "")
    assert xsd.endswith(f"GSDML-DeviceProfile-{m.group(1)}.xsd") and _dap().get("PNIO_Version") == m.group(1)


def test_gsdml_rule_2_profile_header() -> None:
    raw = gsdml_path().read_bytes()
    assert raw.startswith(b'<?xml version="1.0" encoding="utf-8"?>')
    assert _root().tag == "{http://www.profibus.com/GSDML/2003/11/DeviceProfile}ISO15745Profile"
    header = {c.tag.split("}")[1]: (c.text or "").strip() for c in _one("g:ProfileHeader")}
    assert header["ProfileIdentification"] == "PROFINET Device Profile" and header["ProfileClassID"] == "Device"
    assert _one(".//g:ISO15745Part").text == "4" and _one(".//g:ProfileTechnology").text == "GSDML"


def test_gsdml_rule_3_ids_are_the_bitmaps_and_the_devices() -> None:
    ident = _one(".//g:DeviceIdentity")
    for attr in ("VendorID", "DeviceID"):
        assert re.fullmatch(r"0x[0-9A-F]{4}", ident.get(attr, ""))
    bitmap = _one(".//g:GraphicItem").get("GraphicFile", "")
    assert bitmap == f"GSDML-{int(ident.get('VendorID', ''), 16):04X}-{int(ident.get('DeviceID', ''), 16):04X}-WSG"
    assert (int(ident.get("VendorID", ""), 16), int(ident.get("DeviceID", ""), 16)) == (VENDOR_ID, DEVICE_ID)
    assert _one(".//g:VendorName").get("Value") == "Weiss Robotics GmbH & Co. KG"   # 003 §3.1's catalogue path
    assert _one(".//g:Family").get("MainFamily") == "I/O"                          # "PROFINET IO -> I/O"


def test_gsdml_rule_4_ids_unique_and_every_reference_resolves() -> None:
    root = _root()
    ids = [e.get("ID") for e in root.iter() if e.get("ID") is not None]
    assert len(ids) == len(set(ids))
    texts = {t.get("TextId") for t in root.findall(".//g:PrimaryLanguage/g:Text", NS)}
    used = {e.get("TextId") for e in root.iter() if e.get("TextId") and not e.tag.endswith("}Text")}
    assert used <= texts and texts <= used   # no dangling and no unused text
    for ref in root.findall(".//g:ModuleItemRef", NS):
        assert ref.get("ModuleItemTarget") in ids
    for ref in root.findall(".//g:GraphicItemRef", NS):
        assert ref.get("GraphicItemTarget") in ids
    for g in root.findall(".//g:GraphicItem", NS):
        assert g.get("GraphicFile", "") + ".bmp" in descriptions.names()


def test_gsdml_rule_5_device_access_point() -> None:
    dap = _dap()
    lo, hi = (int(x) for x in dap.get("PhysicalSlots", "").split(".."))
    assert dap.get("FixedInSlots") == "0" and lo == 0 and hi == max(s.slot for s in ar.REAL)
    assert name_error(dap.get("DNS_CompatibleName", "")) is None and dap.get("ObjectUUID_LocalIndex") == "1"
    # what the device implements: the device-access AR, WriteMultiple (E040h), a DeviceID check
    for attr in ("DeviceAccessSupported", "MultipleWriteSupported", "CheckDeviceID_Allowed"):
        assert dap.get(attr) == "true", attr
    assert dap.get("SharedDeviceSupported") == "false" and dap.get("AddressAssignment") == "DCP;LOCAL"


def test_gsdml_rule_6_lldp_name_of_device() -> None:
    """PNIO_Version >= V2.3 with LLDP: LLDP_NoD_Supported, and the device's port ID has that form."""
    assert _dap().get("LLDP_NoD_Supported") == "true"
    assert lldp.port_id("wsg50") == "port-001.wsg50"


def test_gsdml_rule_7_reset_to_factory_modes() -> None:
    """Mode 2 (reset communication parameters) is the one DCP Reset to Factory mode the device implements."""
    assert _dap().get("ResetToFactoryModes") == "2"


def test_gsdml_rule_8_certification_info() -> None:
    cert = _one(".//g:CertificationInfo")
    assert cert.get("ConformanceClass") == "A"          # B needs SNMP, C IRT: neither is implemented
    assert cert.get("NetloadClass") in ("I", "II", "III")
    assert cert.get("ApplicationClass", "") == ""       # no class claimed (isochronous, safety, ...)


def test_gsdml_rule_9_interface_and_port_submodules() -> None:
    itf = _one(".//g:InterfaceSubmoduleItem")
    port = _one(".//g:PortSubmoduleItem")
    assert int(itf.get("SubslotNumber", "")) == 0x8000 and int(port.get("SubslotNumber", "")) == 0x8001
    assert itf.get("SupportedRT_Classes") == "RT_CLASS_1"
    protocols = itf.get("SupportedProtocols", "").split(";")
    assert "LLDP" in protocols and "SNMP" not in protocols   # class A: LLDP; no SNMP agent here
    assert itf.find("g:ApplicationRelations/g:TimingProperties", NS) is not None
    maus = {int(m.get("Value", "")) for m in port.findall(".//g:MAUTypeItem", NS)}
    assert maus == {lldp.MAU_100BASE_TXFD}   # what LLDP and PDPortDataReal announce


def test_gsdml_rule_10_ident_numbers_are_the_devices_real_configuration() -> None:
    dap = _dap()
    declared = {(0, 1): (dap.get("ModuleIdentNumber"), _one(".//g:VirtualSubmoduleItem").get(
        "SubmoduleIdentNumber"))}
    for item in (_one(".//g:InterfaceSubmoduleItem"), _one(".//g:PortSubmoduleItem")):
        declared[(0, int(item.get("SubslotNumber", "")))] = (dap.get("ModuleIdentNumber"),
                                                             item.get("SubmoduleIdentNumber"))
    mod = _one(".//g:ModuleItem")
    declared[(1, 1)] = (mod.get("ModuleIdentNumber"), mod.find(".//g:VirtualSubmoduleItem", NS).get(  # type: ignore[union-attr]
        "SubmoduleIdentNumber"))
    real = {(s.slot, s.subslot): (f"0x{s.module_ident:08X}", f"0x{s.submodule_ident:08X}") for s in ar.REAL}
    assert declared == real


def test_gsdml_rule_11_max_lengths_count_iops_and_iocs() -> None:
    """MaxInputLength = input data + one IOPS per submodule sending inputs (a submodule without data counts
    as input) + one IOCS per submodule receiving outputs; MaxOutputLength the other way round."""
    subs = [(s.input_length, s.output_length) for s in ar.REAL]
    inputs = sum(i for i, _ in subs) + sum(1 for i, o in subs if i or not o) + sum(1 for _, o in subs if o)
    outputs = sum(o for _, o in subs) + sum(1 for _, o in subs if o) + sum(1 for i, o in subs if i or not o)
    io = _one(".//g:IOConfigData")
    assert (int(io.get("MaxInputLength", "")), int(io.get("MaxOutputLength", ""))) == (inputs, outputs) == (17, 13)


def test_gsdml_rule_12_data_items() -> None:
    sizes = {"Unsigned8": 1, "Unsigned16": 2, "Integer16": 2, "Unsigned32": 4}
    for item in _root().findall(".//g:DataItem", NS):
        size = int(item.get("Length", "0")) or sizes[item.get("DataType", "")]
        if item.get("UseAsBits") == "true":
            assert item.get("DataType") in ("Unsigned8", "Unsigned16", "Unsigned32", "OctetString")
        for bit in item.findall("g:BitDataItem", NS):
            assert 0 <= int(bit.get("BitOffset", "")) < 8 * size


def test_gsdml_rule_13_channel_diagnosis_types_are_manufacturer_specific() -> None:
    for item in _root().findall(".//g:ChannelDiagItem", NS):
        assert 0x0100 <= int(item.get("ErrorType", "")) <= 0x7FFF


def test_gsdml_rule_14_one_identity_string() -> None:
    """I&M0 OrderID, the GSDML's OrderNumber and the model the web interface shows are one string."""
    web_model = re.sub(r"^([A-Z]+)(\d+)$", r"\1 \2", PROFILES["wsg50"].device_type.name)
    numbers = {e.get("Value") for e in _root().findall(".//g:OrderNumber", NS)}
    assert numbers == {ORDER_ID} == {PROFILES["wsg50"].name} == {web_model} == {"WSG 50"}


def test_gsdml_rule_15_writeable_im_records() -> None:
    """On the DAP's own submodule (the I&M carrier); I&M0 (and I&M5) are read only, so never listed."""
    sub = _dap().find("g:VirtualSubmoduleList/g:VirtualSubmoduleItem", NS)
    assert sub is not None
    declared = {int(x) for x in sub.get("Writeable_IM_Records", "").split()}
    assert declared == {index - im.IM0 for index in im.FIELDS} == {1, 2, 3, 4}
    assert "Writeable_IM_Records" not in _dap().attrib


def test_gsdml_rule_16_mandatory_since_v2_31_and_timing() -> None:
    """MultipleWriteSupported and LLDP_NoD_Supported are mandatory "true" from V2.31 on; SendClock lists 32
    (1 ms) and MinDeviceInterval is a SendClock x ReductionRatio the lists allow."""
    dap = _dap()
    assert dap.get("MultipleWriteSupported") == dap.get("LLDP_NoD_Supported") == "true"
    timing = _one(".//g:InterfaceSubmoduleItem/g:ApplicationRelations/g:TimingProperties")
    clocks = [int(x) for x in timing.get("SendClock", "32").split()]
    ratios = [int(x) for x in timing.get("ReductionRatio", "").split()]
    assert 32 in clocks and int(dap.get("MinDeviceInterval", "")) in {c * r for c in clocks for r in ratios}
