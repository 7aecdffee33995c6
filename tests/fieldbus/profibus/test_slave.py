"""The DP-V0 slave state machine, sans-IO, on a real FieldbusController and virtual gripper
(002 §2.1, §3.3; DP services of IEC 61158-6-3): telegram bytes in, response bytes out."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pywsg.device import ManualClock, VirtualGripper
from pywsg.fieldbus.controller import FieldbusController
from pywsg.fieldbus.image import CmdFlag, OutputImage
from pywsg.fieldbus.profibus import dp as DP
from pywsg.fieldbus.profibus import fdl
from pywsg.fieldbus.profibus.dp import DpSlave, DpState
from pywsg.protocol import SystemFlag

M = 2          # the master's address



class Recorder(FieldbusController):
    """A real controller that also records each fail-safe call."""

    def __init__(self, gripper: Any) -> None:
        super().__init__(gripper)
        self.fail_safes: list[tuple[str, str]] = []

    def fail_safe(self, bus: str, reason: str) -> None:
        self.fail_safes.append((bus, reason))
        parent = getattr(super(), "fail_safe", None)
        if parent is not None:
            parent(bus, reason)


@pytest.fixture
def port() -> Recorder:
    return Recorder(VirtualGripper("wsg50", clock=ManualClock()))


@pytest.fixture
def slave(port: Recorder) -> DpSlave:
    return DpSlave(port, address=7)


class Bus:
    """Sends requests to the slave as a master would, FCB toggled per request."""

    def __init__(self, slave: DpSlave, sa: int = M) -> None:
        self.slave, self.sa, self.fcb, self.now = slave, sa, 0x20, 0.0

    def raw(self, fc: int, data: bytes = b"", dsap: int | None = None, da: int = 7) -> bytes | None:
        tel = fdl.FdlParser().feed(fdl.encode(da, self.sa, fc, data, dsap, 62 if dsap is not None else None))
        assert isinstance(tel[0], fdl.Telegram)
        resp = self.slave.handle(tel[0], self.now)
        self.slave.after_response()
        return resp

    def srd(self, data: bytes = b"", dsap: int | None = None) -> bytes | None:
        fc = 0x4D | self.fcb | 0x10
        self.fcb ^= 0x20
        return self.raw(fc, data, dsap)

    def reply(self, data: bytes = b"", dsap: int | None = None) -> fdl.Telegram:
        resp = self.srd(data, dsap)
        assert resp is not None and resp != fdl.SHORT_ACK, resp
        ev = fdl.FdlParser().feed(resp)[0]
        assert isinstance(ev, fdl.Telegram)
        return ev

    def set_prm(self, status: int = DP.PRM_LOCK_REQ, wd: tuple[int, int] = (1, 1), ident: int = 0x5555,
                group: int = 0, user: bytes = b"") -> bytes | None:
        return self.srd(bytes((status, *wd, 0)) + ident.to_bytes(2, "big") + bytes((group,)) + user, DP.SAP_SET_PRM)

    def connect(self, **kw: Any) -> None:
        assert self.set_prm(**kw) == fdl.SHORT_ACK
        assert self.srd(bytes((0xA7, 0x9B)), DP.SAP_CHK_CFG) == fdl.SHORT_ACK
        assert self.slave.state is DpState.DATA_EXCH

    def diag(self) -> bytes:
        return self.reply(dsap=DP.SAP_SLAVE_DIAG).data


def test_starts_in_wait_prm_with_prm_req_and_no_master(slave: DpSlave) -> None:
    d = Bus(slave).diag()
    assert d[0] & DP.DIAG1_STATION_NOT_READY and d[1] & DP.DIAG2_PRM_REQ and d[1] & DP.DIAG2_ALWAYS_ONE
    assert d[3] == DP.NO_MASTER and d[4:6] == b"\x55\x55"
    assert len(d) == 16 and d[6] == 0x0A                # 002 §3.3: 16 bytes, device block 0Ah


def test_fdl_status_request_gets_a_slave_ok() -> None:
    s = DpSlave(Recorder(VirtualGripper("wsg50", clock=ManualClock())))
    assert Bus(s).raw(0x49) == fdl.encode(M, 7, fdl.RES_OK)


def test_data_exchange_before_parameterisation_is_refused_rs(slave: DpSlave) -> None:
    resp = Bus(slave).srd(bytes(8))
    assert resp == fdl.encode(M, 7, fdl.RES_RS)


def test_set_prm_takes_the_watchdog_and_sync_freeze(slave: DpSlave) -> None:
    bus = Bus(slave)
    bus.connect(status=DP.PRM_LOCK_REQ | DP.PRM_WD_ON | DP.PRM_SYNC_REQ | DP.PRM_FREEZE_REQ, wd=(10, 3))
    assert slave.watchdog_s == pytest.approx(0.3) and slave.sync_enabled and slave.freeze_enabled
    d = bus.diag()
    assert d[0] == 0 and d[1] == DP.DIAG2_ALWAYS_ONE | DP.DIAG2_WD_ON and d[3] == M


def test_user_prm_data_the_gsd_does_not_declare_is_a_prm_fault(slave: DpSlave) -> None:
    bus = Bus(slave)
    assert bus.set_prm(user=b"\x80\x00\x00") == fdl.SHORT_ACK
    assert slave.state is DpState.WAIT_PRM and bus.diag()[0] & DP.DIAG1_PRM_FAULT


def test_data_exchange_carries_the_image_through_the_controller(slave: DpSlave, port: Recorder) -> None:
    bus = Bus(slave)
    bus.connect()
    out = OutputImage(cmdflags=CmdFlag.NONE, if_flags=0x81, width=2000, speed=5000, force_limit=1000).pack()
    resp = bus.reply(out)
    assert resp.fc == fdl.RES_DL and resp.data == port.input_bytes() and len(resp.data) == 12
    assert port.output_bytes == out
    assert bus.reply(b"", DP.SAP_RD_OUTP).data == out
    assert bus.reply(b"", DP.SAP_RD_INP).data == port.input_bytes()
    assert bus.reply(b"", DP.SAP_GET_CFG).data == b"\xa7\x9b"


def test_a_repeated_request_gets_the_same_response_unprocessed(slave: DpSlave, port: Recorder) -> None:
    """FCB/FCV: the master repeats with the same FCB when our response was lost."""
    bus = Bus(slave)
    bus.connect()
    first = OutputImage(if_flags=1).pack()
    resp = bus.srd(first)
    bus.fcb ^= 0x20                                    # the master did not see it: same FCB again
    again = bus.srd(OutputImage(if_flags=2).pack())
    assert again == resp and slave.stats.repeats == 1
    assert port.output_bytes == first                   # the repeat was not applied
    bus.srd(OutputImage(if_flags=3).pack())            # a new FCB: processed
    assert port.output_bytes == OutputImage(if_flags=3).pack()


def test_rising_error_flag_gives_a_high_priority_response_until_the_diag_is_read(
        slave: DpSlave, port: Recorder) -> None:
    """002 §3.3: a diagnosis when SF_FAST_STOP rises; DH until the master reads Slave_Diag."""
    bus = Bus(slave)
    bus.connect()
    assert bus.reply(bytes(8)).fc == fdl.RES_DL
    bus.reply(OutputImage(cmdflags=CmdFlag.FASTSTOP).pack())
    assert bus.reply(OutputImage(cmdflags=CmdFlag.FASTSTOP).pack()).fc == fdl.RES_DH
    d = bus.diag()
    assert d[0] & DP.DIAG1_EXT_DIAG
    assert int.from_bytes(d[7:11], "little") & SystemFlag.SF_FAST_STOP
    assert bus.reply(OutputImage(cmdflags=CmdFlag.FASTSTOP).pack()).fc == fdl.RES_DL


def test_a_flag_going_away_is_no_high_priority_response(slave: DpSlave, port: Recorder) -> None:
    """002 §3.3 / 003 §4.2 name only a flag that "changes from 0 to 1": when the fault goes away the
    responses stay low priority (the master sees it with its next Slave_Diag)."""
    bus = Bus(slave)
    bus.connect()
    bus.reply(bytes(8))
    port.gripper.faults.finger_fault(0, True)
    assert bus.reply(bytes(8)).fc == fdl.RES_DH
    bus.diag()
    port.gripper.faults.finger_fault(0, False)           # the last listed flag goes away
    assert bus.reply(bytes(8)).fc == fdl.RES_DL
    assert int.from_bytes(bus.diag()[7:11], "little") == 0


def test_wrong_output_length_ends_data_exchange_fail_safe(slave: DpSlave, port: Recorder) -> None:
    bus = Bus(slave)
    bus.connect()
    assert bus.srd(bytes(4)) == fdl.encode(M, 7, fdl.RES_RS)
    assert slave.state is DpState.WAIT_PRM and port.fail_safes and "4 output bytes" in port.fail_safes[0][1]


def test_global_control_clear_goes_fail_safe(slave: DpSlave, port: Recorder) -> None:
    bus = Bus(slave)
    bus.connect()
    bus.reply(OutputImage(if_flags=0x0F).pack())
    bus.raw(0x46, bytes((DP.GC_CLEAR_DATA, 0)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    assert port.fail_safes == [("PROFIBUS DP", "Global_Control Clear_Data from master 2")]
    assert slave.outputs == bytes(8) and port.output_bytes == bytes(8)


def test_global_control_for_another_group_or_master_is_ignored(slave: DpSlave, port: Recorder) -> None:
    bus = Bus(slave)
    bus.connect(group=0x01)
    bus.raw(0x46, bytes((DP.GC_CLEAR_DATA, 0x02)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    Bus(slave, sa=3).raw(0x46, bytes((DP.GC_CLEAR_DATA, 0)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    assert port.fail_safes == []


def test_sync_holds_outputs_until_the_next_sync(slave: DpSlave, port: Recorder) -> None:
    bus = Bus(slave)
    bus.connect(status=DP.PRM_LOCK_REQ | DP.PRM_SYNC_REQ)
    gc = 0x46
    bus.raw(gc, bytes((DP.GC_SYNC, 0)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    held = OutputImage(if_flags=0x55).pack()
    bus.reply(held)
    assert port.output_bytes == bytes(8)                # held
    bus.raw(gc, bytes((DP.GC_SYNC, 0)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    assert port.output_bytes == held                    # applied on Sync
    assert bus.diag()[1] & DP.DIAG2_SYNC_MODE
    bus.raw(gc, bytes((DP.GC_UNSYNC, 0)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    bus.reply(OutputImage(if_flags=0x66).pack())
    assert port.output_bytes == OutputImage(if_flags=0x66).pack()


def test_freeze_holds_inputs_and_unsupported_sync_is_reported(slave: DpSlave, port: Recorder) -> None:
    bus = Bus(slave)
    bus.connect(status=DP.PRM_LOCK_REQ | DP.PRM_FREEZE_REQ)
    bus.raw(0x46, bytes((DP.GC_FREEZE, 0)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    frozen = bus.reply(bytes(8)).data
    port.gripper.faults.power_fault(True)
    assert bus.reply(bytes(8)).data == frozen            # frozen: the new SYSSTATE is not shown
    bus.raw(0x46, bytes((DP.GC_UNFREEZE, 0)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    assert bus.reply(bytes(8)).data != frozen
    bus.raw(0x46, bytes((DP.GC_SYNC, 0)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    assert bus.diag()[0] & DP.DIAG1_NOT_SUPPORTED       # Sync was not enabled by Set_Prm


def test_watchdog_expiry_is_fail_safe_and_back_to_wait_prm(slave: DpSlave, port: Recorder) -> None:
    """On expiry in Data_Exch: FAST STOP, zero outputs, Wait_Prm, unlocked."""
    bus = Bus(slave)
    bus.connect(status=DP.PRM_LOCK_REQ | DP.PRM_WD_ON, wd=(10, 1))
    bus.now = 0.05
    bus.reply(OutputImage(if_flags=0x0F).pack())
    assert not slave.check_watchdog(0.14)               # restarted at 0.05: due at 0.15
    assert slave.check_watchdog(0.16)
    assert slave.state is DpState.WAIT_PRM and slave.master is None
    assert port.fail_safes == [("PROFIBUS DP", "watchdog expired")]
    assert port.gripper.system_flags() & SystemFlag.SF_FAST_STOP and port.output_bytes == bytes(8)


def test_a_telegram_after_the_deadline_finds_the_watchdog_expired(slave: DpSlave, port: Recorder) -> None:
    """Expiry is judged on arrival too: a Data_Exchange 150 ms into a 100 ms watchdog (no timer has
    run yet) does not revive the slave; it is refused (RS) and the gripper is already fail-safe."""
    bus = Bus(slave)
    bus.connect(status=DP.PRM_LOCK_REQ | DP.PRM_WD_ON, wd=(10, 1))
    bus.now = 0.15
    assert bus.srd(bytes(8)) == fdl.encode(M, 7, fdl.RES_RS)
    assert slave.state is DpState.WAIT_PRM and port.fail_safes == [("PROFIBUS DP", "watchdog expired")]


def test_the_watchdog_restarts_at_every_telegram_to_the_station(slave: DpSlave) -> None:
    """Any telegram addressed to the slave restarts it, a repeat or another master's diagnosis
    request too; a telegram to another station does not."""
    bus = Bus(slave)
    bus.connect(status=DP.PRM_LOCK_REQ | DP.PRM_WD_ON, wd=(10, 1))
    other = Bus(slave, sa=3)
    other.now = 0.09
    other.diag()
    assert slave.watchdog_deadline == pytest.approx(0.19)
    bus.now = 0.18
    bus.raw(0x49, da=8)                                  # FDL status to station 8
    assert slave.watchdog_deadline == pytest.approx(0.19)


def test_set_prm_rearms_the_watchdog_with_its_new_time(slave: DpSlave) -> None:
    """A Set_Prm that shrinks the watchdog from 2 s to 200 ms: the deadline moves to 200 ms after it."""
    bus = Bus(slave)
    bus.connect(status=DP.PRM_LOCK_REQ | DP.PRM_WD_ON, wd=(200, 1))
    assert slave.watchdog_deadline == pytest.approx(2.0)
    bus.now = 0.5
    bus.connect(status=DP.PRM_LOCK_REQ | DP.PRM_WD_ON, wd=(20, 1))
    assert slave.watchdog_deadline == pytest.approx(0.7)
    bus.now = 0.0
    bus.connect(status=DP.PRM_LOCK_REQ, wd=(20, 1))       # WD_On clear: no watchdog
    assert slave.watchdog_deadline is None and not slave.check_watchdog(100.0)


def test_a_locked_slave_keeps_a_second_master_out_and_sends_master_lock_0(slave: DpSlave) -> None:
    """The slave names its master in diagnosis byte 3; Master_Lock (byte 0 bit 7) is the master's
    to set (it compares byte 3 with its own address), so the slave sends 0."""
    Bus(slave).connect()
    other = Bus(slave, sa=3)
    assert other.set_prm() == fdl.SHORT_ACK
    assert slave.master == M and slave.state is DpState.DATA_EXCH
    d = other.diag()
    assert not d[0] & DP.DIAG1_MASTER_LOCK and d[3] == M
    assert other.srd(bytes(8)) == fdl.encode(3, 7, fdl.RES_RS)


def test_the_fcb_is_judged_against_the_immediately_preceding_frame(slave: DpSlave, port: Recorder) -> None:
    """Master 2's request, then master 3's, then master 2's with the same FCB: not a repeat (the frame
    before it was master 3's), so it is processed."""
    bus = Bus(slave)
    bus.connect()
    bus.srd(OutputImage(if_flags=1).pack())
    Bus(slave, sa=3).srd(b"", DP.SAP_GET_CFG)
    bus.fcb ^= 0x20                                     # same FCB as master 2's last request
    bus.srd(OutputImage(if_flags=2).pack())
    assert port.output_bytes == OutputImage(if_flags=2).pack() and slave.stats.repeats == 0


def test_rd_inp_returns_the_frozen_inputs_during_freeze(slave: DpSlave, port: Recorder) -> None:
    bus = Bus(slave)
    bus.connect(status=DP.PRM_LOCK_REQ | DP.PRM_FREEZE_REQ)
    bus.raw(0x46, bytes((DP.GC_FREEZE, 0)), DP.SAP_GLOBAL_CONTROL, da=fdl.BROADCAST)
    frozen = bus.reply(b"", DP.SAP_RD_INP).data
    port.gripper.faults.power_fault(True)
    assert port.input_bytes() != frozen
    assert bus.reply(b"", DP.SAP_RD_INP).data == frozen


def test_request_ident_names_the_station_and_lsap_status_is_not_offered(slave: DpSlave) -> None:
    """FDL Request Ident (FC 0Eh): four lengths, then vendor, controller type, hardware and software
    release (the GSD's); Request LSAP Status (FC 0Fh): RS, the service is not activated."""
    resp = fdl.FdlParser().feed(Bus(slave).raw(0x4E) or b"")[0]
    assert isinstance(resp, fdl.Telegram) and resp.fc == fdl.RES_DL and resp.da == M
    lengths, text = resp.data[:4], resp.data[4:]
    assert sum(lengths) == len(text) and text.startswith(b"Weiss Robotics")
    assert text[lengths[0]:lengths[0] + lengths[1]] == b"pywsg"
    assert Bus(slave).raw(0x4F, dsap=DP.SAP_SLAVE_DIAG) == fdl.encode(M, 7, fdl.RES_RS)


def test_set_slave_address_in_wait_prm_is_taken_after_the_response(port: Recorder) -> None:
    changed: list[tuple[int, bool]] = []
    s = DpSlave(port, address=7, on_address_change=lambda a, locked: changed.append((a, locked)))
    bus = Bus(s)
    req = bytes((12,)) + b"\x55\x55" + b"\x00"
    assert bus.srd(req, DP.SAP_SET_SLAVE_ADDRESS) == fdl.SHORT_ACK
    assert s.address == 12 and changed == [(12, False)]
    assert bus.raw(0x49) is None                        # the old address is deaf now
    assert bus.raw(0x49, da=12) == fdl.encode(M, 12, fdl.RES_OK)


def test_set_slave_address_refused_with_wrong_ident_or_after_no_add_chg(port: Recorder) -> None:
    s = DpSlave(port, address=7)
    bus = Bus(s)
    assert bus.srd(bytes((12, 0x12, 0x34, 0)), DP.SAP_SET_SLAVE_ADDRESS) == fdl.encode(M, 7, fdl.RES_RS)
    assert bus.srd(bytes((9, 0x55, 0x55, 1)), DP.SAP_SET_SLAVE_ADDRESS) == fdl.SHORT_ACK
    assert s.address == 9
    bus9 = Bus(s)
    bus9.raw = lambda fc, data=b"", dsap=None, da=9: Bus.raw(bus9, fc, data, dsap, da)  # type: ignore[method-assign]
    assert bus9.srd(bytes((10, 0x55, 0x55, 0)), DP.SAP_SET_SLAVE_ADDRESS) == fdl.encode(M, 9, fdl.RES_RS)
    assert s.address == 9
    # After a restart with the stored lock (station.AddressStore) the slave still refuses.
    bus9.slave = DpSlave(port, address=9, address_locked=True)
    assert bus9.srd(bytes((10, 0x55, 0x55, 0)), DP.SAP_SET_SLAVE_ADDRESS) == fdl.encode(M, 9, fdl.RES_RS)


def test_unknown_sap_answers_rs_and_telegrams_for_others_get_nothing(slave: DpSlave) -> None:
    bus = Bus(slave)
    assert bus.srd(b"", 40) == fdl.encode(M, 7, fdl.RES_RS)
    assert bus.raw(0x49, da=8) is None


def test_set_address_from_the_settings_page_drops_the_master_fail_safe(slave: DpSlave, port: Recorder) -> None:
    Bus(slave).connect()
    slave.set_address(20)
    assert slave.state is DpState.WAIT_PRM and slave.master is None and slave.address == 20
    assert port.fail_safes == [("PROFIBUS DP", "station address changed to 20")]
    with pytest.raises(ValueError):
        slave.set_address(126)


@given(fc=st.integers(0, 255), dsap=st.none() | st.integers(0, 63), ssap=st.none() | st.integers(0, 63),
       data=st.binary(max_size=64), sa=st.integers(0, 126))
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_any_telegram_gets_no_exception_and_a_well_formed_answer(
        slave: DpSlave, fc: int, dsap: int | None, ssap: int | None, data: bytes, sa: int) -> None:
    """Whatever a master (or noise with a valid FCS) sends: no exception, and the answer, if any, is
    a short acknowledge or one well-formed telegram to the sender."""
    tel = fdl.Telegram(slave.address, sa, fc, data, dsap, ssap)   # Set_Slave_Address may move it
    resp = slave.handle(tel, 0.0)
    slave.after_response()
    if resp is None or resp == fdl.SHORT_ACK:
        return
    events = fdl.FdlParser().feed(resp)
    assert len(events) == 1 and isinstance(events[0], fdl.Telegram)
    assert events[0].da == sa and not events[0].is_request
