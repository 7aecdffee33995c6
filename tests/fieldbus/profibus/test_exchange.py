"""The PLC side over PROFIBUS DP: ProfibusExchange (pyprofibus DPM1) against the sim's slave on a pty."""

from __future__ import annotations

import asyncio

import pytest

from pywsg.fieldbus.image import InputImage, OutputImage
from pywsg.fieldbus.profibus.exchange import ProfibusError, open_exchange
from pywsg.fieldbus.profibus.master import ProfibusUrl
from pywsg.protocol import GripperState

from ...simthread import SimThread
from .conftest import adapter

pytestmark = pytest.mark.realtime


def test_url_parsing_names_what_is_wrong() -> None:
    u = ProfibusUrl.parse("profibus:///dev/ttyUSB0?address=9&baudrate=9600&watchdog_ms=0")
    assert (u.port, u.address, u.baudrate, u.master, u.watchdog_ms) == ("/dev/ttyUSB0", 9, 9600, 2, 0)
    for bad, says in (("profibus://?address=7", "no serial port"), ("profibus:///dev/x?addr=7", "unknown addr"),
                      ("profibus:///dev/x?address=seven", "integers"), ("profibus:///dev/x?address=2", "different")):
        with pytest.raises(ValueError, match=says):
            ProfibusUrl.parse(bad)


def test_write_then_read_is_one_bus_cycle(pb_sim: SimThread) -> None:
    ad = adapter(pb_sim)

    async def main() -> tuple[bytes, bytes]:
        ex = await open_exchange(f"profibus://{ad.path}?address=7&baudrate=19200", timeout=10)
        try:
            for i in range(1, 30):            # every read answers a request that carried the write before it
                out = OutputImage(if_flags=i, width=100 * i).pack()
                await ex.write_outputs(out)
                first = await ex.read_inputs(timeout=5)
                assert pb_sim.call(lambda: ad.controller.output_bytes) == out, i
            return out, first
        finally:
            await ex.close()

    out, first = asyncio.run(main())
    assert pb_sim.call(lambda: ad.controller.output_bytes) == out
    assert InputImage.unpack(first).state == GripperState.IDLE
    assert ad.slave.master == 2


def test_no_slave_at_that_address_is_a_connection_error(pb_sim: SimThread) -> None:
    ad = adapter(pb_sim)
    with pytest.raises(ProfibusError, match="no DP slave reached Data_Exch"):
        asyncio.run(open_exchange(f"profibus://{ad.path}?address=8", timeout=1))
    assert isinstance(ProfibusError("x"), ConnectionError)


def test_without_pyprofibus_the_error_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "pyprofibus", None)   # import pyprofibus now raises ImportError
    with pytest.raises(ProfibusError, match=r"pip install 'pywsg\[profibus\]'"):
        asyncio.run(open_exchange("profibus:///dev/null?address=7"))


def test_the_device_side_never_imports_pyprofibus() -> None:
    """The slave (MIT) runs without the GPL master library: pyprofibus is the PLC side's extra only."""
    import subprocess
    import sys

    code = ("import sys; import pywsg.fieldbus.profibus.line, pywsg.fieldbus.profibus.exchange, pywsg.server.sim; "
            "import pywsg.cli.main; assert 'pyprofibus' not in sys.modules, 'imported'")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_a_port_that_does_not_exist_is_a_connection_error_naming_it() -> None:
    with pytest.raises(ProfibusError, match=r"^[^\n]*/dev/no-such-rs485[^\n]*$"):
        asyncio.run(open_exchange("profibus:///dev/no-such-rs485?address=7", timeout=1))
