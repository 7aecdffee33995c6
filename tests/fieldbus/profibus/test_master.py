"""pyprofibus (a real DP master) against the virtual WSG's DP slave on a pty (002 §2.1, §3.1–3.3).

The master is configured from pywsg's own WEIS5555.gsd, parsed by pyprofibus's GSD parser.
"""

from __future__ import annotations

import os
import time

import pytest

from pywsg.fieldbus.image import CmdFlag, InputImage, OutputImage
from pywsg.fieldbus.profibus import fdl
from pywsg.fieldbus.profibus.dp import DpState
from pywsg.protocol import GripperState, SystemFlag

from ...simthread import SimThread
from .conftest import adapter
from .pbmaster import MASTER, dp_master, pyprofibus, run_until, start

pytestmark = pytest.mark.realtime


def _wait(cond: object, what: str, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if callable(cond) and cond():
            return
        time.sleep(0.005)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def test_parameterize_configure_and_exchange_data(pb_sim: SimThread) -> None:
    """002 §3.1/§3.2: 8 output bytes reach the FieldbusController, 12 input bytes come back."""
    ad = adapter(pb_sim)
    with dp_master(ad.path) as (master, desc):
        start(master, desc)
        inputs = run_until(master, desc, lambda d: d is not None, "the first Data_Exchange")
        assert inputs is not None and len(inputs) == 12
        assert ad.slave.state is DpState.DATA_EXCH and ad.slave.master == MASTER
        # Outputs: IF flags 0xA5 and a width; they land in the controller's output image.
        out = OutputImage(if_flags=0xA5, width=1234).pack()   # 12.34 mm in 1/100 mm
        run_until(master, desc, lambda d: pb_sim.call(lambda: ad.controller.output_bytes) == out,
                  "the outputs in the controller", out=out)
        image = InputImage.unpack(run_until(master, desc, lambda d: d is not None, "inputs", out=out) or b"")
        assert image.state == GripperState.IDLE
        assert ad.bus_state()["Interface state"] == "Online"
        assert ad.bus_state()["Station Address"] == "7"
    assert ad.slave.stats.data_exchanges >= 2


def test_homing_over_the_bus_moves_the_gripper(pb_sim: SimThread) -> None:
    """002 §4.4: a HOMING edge over PROFIBUS starts a homing; SF_REFERENCED comes back in SYSSTATE."""
    ad = adapter(pb_sim)
    with dp_master(ad.path) as (master, desc):
        start(master, desc)
        run_until(master, desc, lambda d: d is not None, "Data_Exch")
        homing = OutputImage(cmdflags=CmdFlag.HOMING).pack()

        def referenced(d: bytes | None) -> bool:
            return d is not None and bool(InputImage.unpack(d).sysstate & SystemFlag.SF_REFERENCED) \
                and InputImage.unpack(d).state == GripperState.IDLE
        run_until(master, desc, referenced, "homing done (SF_REFERENCED, IDLE)", out=homing, timeout=20)


def test_wrong_ident_number_is_refused_with_prm_fault(pb_sim: SimThread) -> None:
    """Set_Prm with an Ident_Number other than 5555h: Prm_Fault in the diagnosis, no Data_Exch."""
    ad = adapter(pb_sim)
    with dp_master(ad.path) as (master, desc):
        desc.setPrmTelegram.identNumber = 0x1234
        start(master, desc)
        run_until(master, desc, lambda d: ad.slave.prm_fault, "the slave to refuse Set_Prm")
        _spin(master, desc, 0.2)
        assert not desc.isConnected()
        assert ad.slave.state is DpState.WAIT_PRM and ad.slave.prm_fault
        diag = _slave_diag(master)
    assert diag.prmFault() and diag.prmReq() and not diag.isReadyDataEx()
    assert diag.identNumber == 0x5555


def test_wrong_configuration_is_refused_with_cfg_fault(pb_sim: SimThread) -> None:
    """Chk_Cfg other than the GSD module (A7 9B): Cfg_Fault in the diagnosis, no Data_Exch."""
    ad = adapter(pb_sim)
    with dp_master(ad.path) as (master, desc):
        desc.setCfgDataElements([pyprofibus.dp.DpCfgDataElement(0x97), pyprofibus.dp.DpCfgDataElement(0xA7)])
        start(master, desc)
        run_until(master, desc, lambda d: ad.slave.cfg_fault, "the slave to refuse Chk_Cfg")
        _spin(master, desc, 0.2)
        assert not desc.isConnected()
        # The master starts over (Set_Prm again): Cfg_Fault stays until a Chk_Cfg matches.
        assert ad.slave.cfg_fault and ad.slave.state is not DpState.DATA_EXCH
        assert "the GSD module is a7 9b" in ad.slave.last_reason
        diag = _slave_diag(master)
    assert diag.cfgFault() and not diag.prmFault() and diag.notReady() and not diag.isReadyDataEx()


def test_watchdog_expires_when_the_master_stops(pb_sim: SimThread) -> None:
    """Set_Prm WD_On (200 ms): the master falls silent → fail-safe, Wait_Prm, the Bus State says why."""
    ad = adapter(pb_sim)
    with dp_master(ad.path, watchdog_ms=200) as (master, desc):
        start(master, desc)
        run_until(master, desc, lambda d: d is not None, "Data_Exch")
        assert ad.slave.watchdog_s == pytest.approx(0.2)
    _wait(lambda: ad.slave.state is DpState.WAIT_PRM, "the watchdog to expire")
    assert ad.slave.stats.watchdog_expiries == 1
    assert "watchdog expired" in ad.bus_state()["Interface state"]


def test_garbage_and_torn_telegrams_on_the_line_do_not_stop_the_exchange(pb_sim: SimThread) -> None:
    """Stray bytes and bad FCS between the master's telegrams: no answer to them, the exchange goes on."""
    ad = adapter(pb_sim)
    with dp_master(ad.path) as (master, desc):
        start(master, desc)
        run_until(master, desc, lambda d: d is not None, "Data_Exch")
        fd = os.open(ad.path, os.O_WRONLY | os.O_NOCTTY)
        try:
            good = fdl.encode(7, MASTER, 0x7D, bytes(8))
            bad_fcs = good[:-2] + bytes([(good[-2] + 1) & 0xFF]) + good[-1:]
            for junk in (b"\x00\xff\x55", bad_fcs, good[:5], b"\x68\x05\x06\x68", os.urandom(64)):
                os.write(fd, junk)
                run_until(master, desc, lambda d: d is not None, "Data_Exchange after junk")
        finally:
            os.close(fd)
        before = ad.slave.stats.data_exchanges
        run_until(master, desc, lambda d: ad.slave.stats.data_exchanges > before + 5, "more cycles")
    assert ad.line_errors > 0


def _spin(master: object, desc: object, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        desc.setMasterOutData(bytearray(8))  # type: ignore[attr-defined]
        master.run()  # type: ignore[attr-defined]
        time.sleep(0.0002)


def _slave_diag(master: object) -> object:
    """One Slave_Diag request through pyprofibus's own DP transceiver; its parsed response."""
    trans = master.dpTrans  # type: ignore[attr-defined]
    fcb = pyprofibus.fdl.FdlFCB(enable=False)
    for _ in range(20):
        trans.send(fcb, pyprofibus.dp.DpTelegram_SlaveDiag_Req(da=7, sa=MASTER))
        deadline = time.monotonic() + 0.5
        while time.monotonic() < deadline:
            try:
                ok, tel = trans.poll(timeout=0.05)
            except pyprofibus.ProfibusError:
                continue
            if ok and pyprofibus.dp.DpTelegram_SlaveDiag_Con.checkType(tel):
                return tel
    raise AssertionError("no Slave_Diag response")


def test_set_slave_address_persists_in_the_interface_settings(pb_factory: object, tmp_path: object) -> None:
    """Set_Slave_Address (SAP 55) in Wait_Prm: the slave answers at the new address, and the address is
    stored as ``profibus_address`` beside the settings file (002 §2.1.2: the station address can be
    changed), where the next start reads it."""
    import json
    import select
    from pathlib import Path

    settings = Path(str(tmp_path)) / "s.json"
    sim = pb_factory(tcp_port=None, udp_port=None, profibus="pty", settings=settings)  # type: ignore[operator]
    ad = adapter(sim)
    fd = os.open(ad.path, os.O_RDWR | os.O_NOCTTY)
    try:
        import tty

        tty.setraw(fd)
        os.write(fd, fdl.encode(7, MASTER, 0x4D, bytes((33, 0x55, 0x55, 0)), dsap=55, ssap=62))
        assert select.select([fd], [], [], 5)[0], "no answer to Set_Slave_Address"
        assert os.read(fd, 64) == fdl.SHORT_ACK
        os.write(fd, fdl.encode(33, MASTER, 0x49))          # FDL status at the new address
        assert select.select([fd], [], [], 5)[0], "no answer at address 33"
        assert os.read(fd, 64) == fdl.encode(MASTER, 33, fdl.RES_OK)
    finally:
        os.close(fd)
    stored = json.loads((settings.parent / "s.interface.json").read_text())
    assert stored["profibus_address"] == 33
    assert ad.bus_state()["Station Address"] == "33"


def test_a_rising_fast_stop_reaches_the_master_as_a_diagnosis(pb_sim: SimThread) -> None:
    """002 §3.3: SF_FAST_STOP rises → the slave answers Data_Exchange high priority (DH); pyprofibus
    fetches Slave_Diag (with Ext_Diag and SYSSTATE) and goes back to Data_Exch on its own."""
    ad = adapter(pb_sim)
    with dp_master(ad.path) as (master, desc):
        start(master, desc)
        run_until(master, desc, lambda d: d is not None, "Data_Exch")
        fast_stop = OutputImage(cmdflags=CmdFlag.FASTSTOP).pack()

        def fast_stop_seen(d: bytes | None) -> bool:
            return d is not None and bool(InputImage.unpack(d).sysstate & SystemFlag.SF_FAST_STOP)
        run_until(master, desc, fast_stop_seen, "SF_FAST_STOP in the inputs", out=fast_stop)
        run_until(master, desc, lambda d: ad.slave.stats.high_priority > 0 and not ad.slave.diagnosis_pending,
                  "the master to read the diagnosis", out=fast_stop)
        run_until(master, desc, lambda d: desc.isConnected() and d is not None, "Data_Exch again", out=fast_stop)
        diag = ad.slave.diagnosis(MASTER)
    assert diag[0] & 0x08 and int.from_bytes(diag[7:11], "little") & SystemFlag.SF_FAST_STOP   # Ext_Diag, SYSSTATE


def test_global_control_clear_from_pyprofibus_is_fail_safe(pb_sim: SimThread) -> None:
    """Global_Control Clear_Data (broadcast, SAP 58) from the locking master: the controller's fail-safe
    (FAST STOP, docs/fidelity.md) shows in the inputs of the next Data_Exchange."""
    ad = adapter(pb_sim)
    with dp_master(ad.path) as (master, desc):
        start(master, desc)
        run_until(master, desc, lambda d: d is not None, "Data_Exch")
        gc = pyprofibus.dp.DpTelegram_GlobalControl(da=fdl.BROADCAST, sa=MASTER)
        gc.controlCommand = gc.CCMD_CLEAR

        def fast_stop(d: bytes | None) -> bool:
            seen = d is not None and bool(InputImage.unpack(d).sysstate & SystemFlag.SF_FAST_STOP)
            if not seen and desc.isConnected():   # (again, if the slave was being re-parameterised)
                master.dpTrans.send(pyprofibus.fdl.FdlFCB(enable=False), gc)
            return seen
        run_until(master, desc, fast_stop, "FAST STOP after Clear_Data")


def test_sync_and_freeze_from_pyprofibus(pb_sim: SimThread) -> None:
    """Set_Prm with Sync_Req/Freeze_Req, then pyprofibus's own Global_Control Sync and Freeze put the
    slave in Sync and Freeze mode (its diagnosis says so). What they hold is tested without a master's
    timing in test_slave.py (a loaded host may make pyprofibus re-parameterise, which ends both)."""
    ad = adapter(pb_sim)
    with dp_master(ad.path) as (master, desc):
        desc.setSyncMode(True)
        desc.setFreezeMode(True)
        start(master, desc)
        run_until(master, desc, lambda d: d is not None, "Data_Exch")
        assert ad.slave.sync_enabled and ad.slave.freeze_enabled

        # One Global_Control with both commands: pyprofibus's syncMode() and freezeMode() each queue a
        # telegram for the broadcast address, and its PHY keeps only the last one queued per address.
        gc = pyprofibus.dp.DpTelegram_GlobalControl(da=fdl.BROADCAST, sa=MASTER)
        gc.controlCommand = gc.CCMD_SYNC | gc.CCMD_FREEZE

        def both_modes(d: bytes | None) -> bool:
            if not (ad.slave.sync_mode and ad.slave.freeze_mode) and desc.isConnected():
                master.dpTrans.send(pyprofibus.fdl.FdlFCB(enable=False), gc)   # (again after a re-Set_Prm)
            return ad.slave.sync_mode and ad.slave.freeze_mode
        run_until(master, desc, both_modes, "Sync and Freeze modes")
        diag = ad.slave.diagnosis(MASTER)
    assert diag[1] & 0x30 == 0x30                                      # Freeze_Mode and Sync_Mode bits


def test_no_further_address_change_is_persisted_with_the_address(pb_factory: object, tmp_path: object) -> None:
    """Set_Slave_Address with No_Add_Chg: stored beside the address, so after a restart the slave at
    its new address still refuses (RS) another Set_Slave_Address."""
    import json
    import select
    import tty
    from pathlib import Path

    settings = Path(str(tmp_path)) / "s.json"

    def ask(sim: object, request: bytes) -> bytes:
        fd = os.open(adapter(sim).path, os.O_RDWR | os.O_NOCTTY)   # type: ignore[arg-type]
        try:
            tty.setraw(fd)
            os.write(fd, request)
            assert select.select([fd], [], [], 5)[0], f"no answer to {request.hex(' ')}"
            time.sleep(0.01)
            return os.read(fd, 64)
        finally:
            os.close(fd)

    first = pb_factory(tcp_port=None, udp_port=None, profibus="pty", settings=settings)  # type: ignore[operator]
    assert ask(first, fdl.encode(7, MASTER, 0x4D, bytes((33, 0x55, 0x55, 1)), dsap=55, ssap=62)) == fdl.SHORT_ACK
    first.stop()
    stored = json.loads((settings.parent / "s.interface.json").read_text())
    assert stored["profibus_address"] == 33 and stored["profibus_address_locked"] is True
    again = pb_factory(tcp_port=None, udp_port=None, profibus="pty", settings=settings)  # type: ignore[operator]
    assert adapter(again).address == 33
    refused = ask(again, fdl.encode(33, MASTER, 0x4D, bytes((34, 0x55, 0x55, 0)), dsap=55, ssap=62))
    assert refused == fdl.encode(MASTER, 33, fdl.RES_RS) and adapter(again).address == 33
