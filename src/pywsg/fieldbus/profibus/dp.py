"""The WSG as a PROFIBUS DP-V0 slave, sans-IO: telegram in, response bytes out (002 §2.1, §3.3).

State machine (IEC 61158-6-3 / EN 50170 DP-V0): **Wait_Prm → Wait_Cfg → Data_Exch**.

- Set_Prm (SAP 61) from a master with Lock_Req: Ident_Number must be 5555h and there must be no
  User_Prm_Data (the GSD declares none), else Prm_Fault in the diagnosis and Wait_Prm. It takes the
  watchdog (WD_On, 10 ms × WD_Fact_1 × WD_Fact_2), Sync/Freeze enables, Group_Ident, min TSDR and
  locks the slave to that master.
- Chk_Cfg (SAP 62): the configuration must equal the GSD module's (``A7 9B``: 8 bytes out, 12 bytes
  in, each consistent), else Cfg_Fault and Wait_Prm.
- Data_Exchange (default SAP): 8 output bytes go to the FieldbusController, the 12 input bytes come
  back; the response is high priority (DH) while a new diagnosis waits: one of the manual's
  error-related flags rose (002 §3.3 / 003 §4.2; a flag going away is not news: docs/fidelity.md).
- Slave_Diag (60): 6 standard bytes + the manual's 10-byte device-related block with SYSSTATE.
- Global_Control (58): Clear_Data → fail-safe; Sync/Unsync, Freeze/Unfreeze.
- Get_Cfg (59), Rd_Inp (56; the frozen inputs during Freeze), Rd_Outp (57), Set_Slave_Address (55,
  only in Wait_Prm; the address and its No_Add_Chg persisted by the caller's ``on_address_change``).
- FDL: Request FDL Status (every station answers it) and Request Ident (vendor, controller,
  hardware and software release from the GSD); Request LSAP Status gets RS (not offered).
- Watchdog (WD_On): the deadline restarts at every telegram addressed to this station and is judged
  on arrival too, so a telegram after the deadline finds the slave already expired; on expiry the
  controller goes fail-safe (FAST STOP, zero outputs) when in Data_Exch, and the slave to Wait_Prm.
- FCB/FCV: a request that repeats the FCB of the immediately preceding frame from the same master
  (FCV=1) gets the stored response again, unprocessed. One frame is remembered, not one per master.
- Master_Lock (diagnosis byte 0 bit 7) is sent 0: the standard has the master set it.

Times are ``time.monotonic()`` seconds passed in by the caller: bus watchdogs run on real time, not on
the gripper's (possibly manual) clock.
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from ...protocol import SystemFlag
from ..image import INPUT_SIZE, OUTPUT_SIZE, OutputImage, sysstate_bytes, sysstate_from_bytes
from . import fdl
from .diagnosis import DIAGNOSIS_FLAGS, DIAGNOSIS_LENGTH
from .gsd import facts

log = logging.getLogger("pywsg.fieldbus.profibus")

BUS_NAME = "PROFIBUS DP"

# DP service access points (destination SAP at the slave).
SAP_SET_SLAVE_ADDRESS = 55
SAP_RD_INP = 56
SAP_RD_OUTP = 57
SAP_GLOBAL_CONTROL = 58
SAP_GET_CFG = 59
SAP_SLAVE_DIAG = 60
SAP_SET_PRM = 61
SAP_CHK_CFG = 62

# Set_Prm Station_Status.
PRM_WD_ON = 0x08
PRM_FREEZE_REQ = 0x10
PRM_SYNC_REQ = 0x20
PRM_UNLOCK_REQ = 0x40
PRM_LOCK_REQ = 0x80

# Global_Control Control_Command.
GC_CLEAR_DATA = 0x02
GC_UNFREEZE = 0x04
GC_FREEZE = 0x08
GC_UNSYNC = 0x10
GC_SYNC = 0x20

# Slave_Diag Station_Status_1 / _2.
DIAG1_STATION_NOT_READY = 0x02
DIAG1_CFG_FAULT = 0x04
DIAG1_EXT_DIAG = 0x08
DIAG1_NOT_SUPPORTED = 0x10
DIAG1_PRM_FAULT = 0x40
DIAG1_MASTER_LOCK = 0x80
DIAG2_PRM_REQ = 0x01
DIAG2_ALWAYS_ONE = 0x04
DIAG2_WD_ON = 0x08
DIAG2_FREEZE_MODE = 0x10
DIAG2_SYNC_MODE = 0x20
NO_MASTER = 0xFF

MAX_STATION_ADDRESS = 125   # 126 is the commissioning default, 127 broadcast


class DpState(enum.Enum):
    """The DP slave states (names as the DP standard writes them)."""

    WAIT_PRM = "Wait_Prm"
    WAIT_CFG = "Wait_Cfg"
    DATA_EXCH = "Data_Exch"


class ImagePort(Protocol):
    """What the slave needs from :class:`pywsg.fieldbus.controller.FieldbusController`."""

    def write_outputs(self, image: OutputImage) -> None: ...

    def input_bytes(self) -> bytes: ...

    def fail_safe(self, bus: str, reason: str) -> None: ...


def ident_data() -> bytes:
    """The data unit of the answer to Request Ident (IEC 61158-4-3): four length bytes, then the
    vendor name, controller type, hardware release and software release, from the GSD."""
    gsd = facts()
    parts = [t.encode("latin-1")[:255] for t in (gsd.vendor_name, gsd.implementation_type,
                                                  gsd.hardware_release, gsd.software_release)]
    return bytes(len(p) for p in parts) + b"".join(parts)


def fail_safe(port: ImagePort, reason: str) -> None:
    """What the gripper does when its master is lost: the controller's one rule for every bus
    (FAST STOP, outputs to zero; docs/fidelity.md "Fieldbus master lost")."""
    port.fail_safe(BUS_NAME, reason)


@dataclass
class SlaveStats:
    """Counters for the Fieldbus Monitor and the benchmark."""

    requests: int = 0
    data_exchanges: int = 0
    repeats: int = 0
    refused: int = 0
    watchdog_expiries: int = 0
    high_priority: int = 0


class DpSlave:
    """One DP-V0 slave at ``address`` serving ``port`` (the FieldbusController)."""

    def __init__(self, port: ImagePort, address: int = 7,
                 on_address_change: Callable[[int, bool], None] | None = None,
                 address_locked: bool = False) -> None:
        if not 0 <= address <= MAX_STATION_ADDRESS:
            raise ValueError(f"PROFIBUS station address is 0..{MAX_STATION_ADDRESS}, got {address}")
        gsd = facts()
        self.port = port
        self.address = address
        self.ident_number = gsd.ident_number
        self.config = gsd.config
        self.user_prm_len = gsd.user_prm_len
        self.on_address_change = on_address_change
        self.state = DpState.WAIT_PRM
        self.stats = SlaveStats()
        self.master: int | None = None          # the master the slave is locked to
        self.group = 0
        self.watchdog_s: float | None = None
        self.watchdog_deadline: float | None = None
        self.min_tsdr = 11                      # bit times; Set_Prm may raise it
        self.sync_enabled = self.freeze_enabled = False
        self.sync_mode = self.freeze_mode = False
        self.prm_fault = self.cfg_fault = self.not_supported = False
        self.address_locked = address_locked    # Set_Slave_Address No_Add_Chg (persisted)
        self.outputs = bytes(OUTPUT_SIZE)       # last outputs applied (Rd_Outp)
        self._sync_pending: bytes | None = None
        self._frozen: bytes | None = None
        self._sysstate = SystemFlag.NONE
        self._diag_pending = False               # a new diagnosis the master has not read
        # The immediately preceding frame: (SA, FCB or None without FCV, our response).
        self._last: tuple[int, int | None, bytes | None] | None = None
        self._pending_address: int | None = None
        self.last_reason = ""                   # why the slave last left Data_Exch / refused

    @property
    def diagnosis_pending(self) -> bool:
        """A new diagnosis the locking master has not read yet (Data_Exchange answers DH)."""
        return self._diag_pending

    # --- the entry point ---------------------------------------------------------------------
    def handle(self, tel: fdl.Telegram, now: float) -> bytes | None:
        """The response to ``tel`` (bytes to put on the line), or None: no answer. ``now`` is when
        the telegram arrived (monotonic s): the watchdog is judged against it before anything else."""
        if not tel.is_request or tel.da not in (self.address, fdl.BROADCAST):
            return None
        self.check_watchdog(now)                    # a late telegram finds the watchdog expired
        func = tel.function
        if tel.da == fdl.BROADCAST:
            if func in (fdl.REQ_SDN_HI, fdl.REQ_SDN_LO) and tel.dsap == SAP_GLOBAL_CONTROL:
                if tel.sa == self.master:
                    self._touch(now)
                self._global_control(tel, now)
            return None
        self.stats.requests += 1
        self._touch(now)                            # any telegram to this station, a repeat too
        if func in (fdl.REQ_FDL_STATUS, fdl.REQ_IDENT, fdl.REQ_LSAP_STATUS):
            self._last = (tel.sa, None, None)
            return self._fdl_management(tel)
        if func in (fdl.REQ_SDN_HI, fdl.REQ_SDN_LO):
            self._last = (tel.sa, None, None)
            if tel.dsap == SAP_GLOBAL_CONTROL:
                self._global_control(tel, now)
            return None
        if func not in (fdl.REQ_SRD_HI, fdl.REQ_SRD_LO, fdl.REQ_SDA_HI, fdl.REQ_SDA_LO):
            return None                              # time events, clock values: not offered
        fcb = tel.fc & fdl.FC_FCB if tel.fc & fdl.FC_FCV else None
        last = self._last
        if fcb is not None and last is not None and last[0] == tel.sa and last[1] == fcb:
            self.stats.repeats += 1                 # the master lost our response: send it again
            return last[2]
        response = self._service(tel, now)
        if func in (fdl.REQ_SDA_HI, fdl.REQ_SDA_LO):
            response = fdl.SHORT_ACK
        self._last = (tel.sa, fcb, response)
        return response

    def _fdl_management(self, tel: fdl.Telegram) -> bytes:
        """FDL Status: "slave, OK" (a master's live list); Ident: the GSD's names; LSAP Status: RS."""
        func = tel.function
        if func == fdl.REQ_FDL_STATUS:
            return fdl.encode(tel.sa, self.address, fdl.RES_OK)
        if func == fdl.REQ_IDENT:
            return fdl.encode(tel.sa, self.address, fdl.RES_DL, ident_data())
        return self._rs(tel)

    def after_response(self) -> None:
        """Call once the response has been put on the line (Set_Slave_Address takes effect now)."""
        new, self._pending_address = self._pending_address, None
        if new is not None and new != self.address:
            log.info("PROFIBUS DP: station address %d -> %d (Set_Slave_Address)", self.address, new)
            self.address = new
            self._last = None
            if self.on_address_change is not None:
                self.on_address_change(new, self.address_locked)

    def set_address(self, address: int) -> None:
        """Change the station address from outside the bus (Settings → Command Interface). A master
        in Data_Exch loses the slave: fail-safe, Wait_Prm, unlocked."""
        if not 0 <= address <= MAX_STATION_ADDRESS:
            raise ValueError(f"PROFIBUS station address is 0..{MAX_STATION_ADDRESS}, got {address}")
        if address == self.address:
            return
        if self.state is not DpState.WAIT_PRM:
            self._leave(f"station address changed to {address}", safe=self.state is DpState.DATA_EXCH)
        self.master = None
        self.address = address
        self._last = None

    def check_watchdog(self, now: float) -> bool:
        """Expire the watchdog if its time has come (``now`` in monotonic s); True when it did."""
        if self.watchdog_deadline is None or now < self.watchdog_deadline:
            return False
        self.watchdog_deadline = None
        self.stats.watchdog_expiries += 1
        log.warning("PROFIBUS DP station %d: watchdog expired (%.0f ms without a telegram)",
                    self.address, 1000 * (self.watchdog_s or 0))
        self._leave("watchdog expired", safe=self.state is DpState.DATA_EXCH)
        self.master = None
        return True

    # --- services ----------------------------------------------------------------------------
    def _service(self, tel: fdl.Telegram, now: float) -> bytes | None:
        sap = tel.dsap
        if sap is None:
            return self._data_exchange(tel, now)
        if tel.ssap is None:
            return self._rs(tel)
        handler = _SERVICES.get(sap)
        if handler is None:
            return self._rs(tel)
        return handler(self, tel, now)

    def _data_exchange(self, tel: fdl.Telegram, now: float) -> bytes:
        if self.state is not DpState.DATA_EXCH or tel.sa != self.master:
            self.stats.refused += 1
            return self._rs(tel)
        if len(tel.data) != OUTPUT_SIZE:
            # The DP standard: outputs of the wrong length end Data_Exch; the master must start over.
            self._leave(f"Data_Exchange with {len(tel.data)} output bytes, expected {OUTPUT_SIZE}",
                        safe=True)
            return self._rs(tel)
        self.stats.data_exchanges += 1
        if self.sync_mode:
            self._sync_pending = tel.data
        else:
            self._apply(tel.data)
        fresh = self.port.input_bytes()
        self._watch_diag(fresh)
        inputs = self._frozen if self.freeze_mode and self._frozen is not None else fresh
        fc = fdl.RES_DH if self._diag_pending else fdl.RES_DL
        if self._diag_pending:
            self.stats.high_priority += 1
        return fdl.encode(tel.sa, self.address, fc, inputs)

    def _slave_diag(self, tel: fdl.Telegram, now: float) -> bytes:
        fresh = self.port.input_bytes()
        self._watch_diag(fresh)
        if tel.sa == self.master or self.master is None:
            self._diag_pending = False          # the (locking) master has read it
        return self._reply(tel, self.diagnosis(tel.sa, fresh))

    def diagnosis(self, requester: int | None = None, inputs: bytes | None = None) -> bytes:
        """The 16-byte Slave_Diag data: standard bytes + the manual's device-related block (002 §3.3)."""
        sysstate = sysstate_from_bytes((inputs or self.port.input_bytes())[2:6])
        s1 = 0
        if self.state is not DpState.DATA_EXCH:
            s1 |= DIAG1_STATION_NOT_READY
        if self.cfg_fault:
            s1 |= DIAG1_CFG_FAULT
        if sysstate & DIAGNOSIS_FLAGS:
            s1 |= DIAG1_EXT_DIAG
        if self.not_supported:
            s1 |= DIAG1_NOT_SUPPORTED
        if self.prm_fault:
            s1 |= DIAG1_PRM_FAULT
        # Master_Lock (bit 7) stays 0: the master sets it when another master's address is in byte 3.
        s2 = DIAG2_ALWAYS_ONE
        if self.state is DpState.WAIT_PRM:
            s2 |= DIAG2_PRM_REQ
        if self.watchdog_s is not None:
            s2 |= DIAG2_WD_ON
        if self.freeze_mode:
            s2 |= DIAG2_FREEZE_MODE
        if self.sync_mode:
            s2 |= DIAG2_SYNC_MODE
        master = NO_MASTER if self.master is None else self.master
        return (bytes((s1, s2, 0, master)) + self.ident_number.to_bytes(2, "big")
                + bytes((DIAGNOSIS_LENGTH,)) + sysstate_bytes(sysstate) + bytes(5))

    def _set_prm(self, tel: fdl.Telegram, now: float) -> bytes:
        data = tel.data
        if len(data) < 7:
            self.prm_fault = True
            self.last_reason = f"Set_Prm with {len(data)} bytes (at least 7)"
            return fdl.SHORT_ACK
        status, wd1, wd2, min_tsdr = data[0], data[1], data[2], data[3]
        ident = int.from_bytes(data[4:6], "big")
        lock, unlock = bool(status & PRM_LOCK_REQ), bool(status & PRM_UNLOCK_REQ)
        if self.master is not None and tel.sa != self.master:
            return fdl.SHORT_ACK                 # locked to another master: Master_Lock in its diag
        if unlock:
            self._leave(f"unlocked by master {tel.sa}", safe=self.state is DpState.DATA_EXCH)
            self.master = None
            return fdl.SHORT_ACK
        if not lock:
            if min_tsdr and self.master == tel.sa:
                self.min_tsdr = min_tsdr         # Lock=Unlock=0: only min TSDR changes
            return fdl.SHORT_ACK
        fault = ""
        if ident != self.ident_number:
            fault = f"Set_Prm Ident_Number {ident:04X}h, this slave is {self.ident_number:04X}h"
        elif len(data) - 7 != self.user_prm_len:
            fault = f"Set_Prm with {len(data) - 7} bytes of User_Prm_Data, the GSD declares {self.user_prm_len}"
        elif status & PRM_WD_ON and (wd1 == 0 or wd2 == 0):
            fault = "Set_Prm WD_On with a watchdog factor 0"
        if fault:
            self.prm_fault = True
            self.last_reason = fault
            log.warning("PROFIBUS DP: %s", fault)
            if self.state is not DpState.WAIT_PRM:
                self._leave(fault, safe=self.state is DpState.DATA_EXCH)
            return fdl.SHORT_ACK
        self.prm_fault = self.not_supported = False   # Cfg_Fault stays until the next Chk_Cfg
        if self.state is DpState.DATA_EXCH:
            self._leave("new Set_Prm", safe=False)
        self.master = tel.sa
        self.watchdog_s = 0.010 * wd1 * wd2 if status & PRM_WD_ON else None
        self.watchdog_deadline = None            # re-armed below with the new time (or off)
        self.sync_enabled = bool(status & PRM_SYNC_REQ)
        self.freeze_enabled = bool(status & PRM_FREEZE_REQ)
        self.sync_mode = self.freeze_mode = False
        self.group = data[6]
        if min_tsdr:
            self.min_tsdr = min_tsdr
        self.state = DpState.WAIT_CFG
        self._touch(now)
        return fdl.SHORT_ACK

    def _chk_cfg(self, tel: fdl.Telegram, now: float) -> bytes:
        if self.state is DpState.WAIT_PRM or tel.sa != self.master:
            return fdl.SHORT_ACK                 # not accepted before Set_Prm (Prm_Req stays set)
        if tel.data != self.config:
            self.cfg_fault = True
            self.last_reason = f"Chk_Cfg {tel.data.hex(' ')}, the GSD module is {self.config.hex(' ')}"
            log.warning("PROFIBUS DP: %s", self.last_reason)
            self._leave(self.last_reason, safe=self.state is DpState.DATA_EXCH)
            return fdl.SHORT_ACK
        self.cfg_fault = False
        if self.state is not DpState.DATA_EXCH:
            self.state = DpState.DATA_EXCH
            self._sysstate = SystemFlag.NONE     # a fault present at start is news to this master
            self.last_reason = ""
            log.info("PROFIBUS DP: station %d in Data_Exch with master %d", self.address, tel.sa)
        return fdl.SHORT_ACK

    def _global_control_srd(self, tel: fdl.Telegram, now: float) -> bytes:
        self._global_control(tel, now)
        return fdl.SHORT_ACK

    def _get_cfg(self, tel: fdl.Telegram, now: float) -> bytes:
        return self._reply(tel, self.config)

    def _rd_inp(self, tel: fdl.Telegram, now: float) -> bytes:
        if self.state is not DpState.DATA_EXCH:
            return self._rs(tel)
        frozen = self._frozen if self.freeze_mode else None
        return self._reply(tel, frozen if frozen is not None else self.port.input_bytes())

    def _rd_outp(self, tel: fdl.Telegram, now: float) -> bytes:
        if self.state is not DpState.DATA_EXCH:
            return self._rs(tel)
        return self._reply(tel, self.outputs)

    def _set_slave_address(self, tel: fdl.Telegram, now: float) -> bytes:
        data = tel.data
        if len(data) < 4 or self.state is not DpState.WAIT_PRM or self.address_locked:
            return self._rs(tel)
        new, ident, no_add_chg = data[0], int.from_bytes(data[1:3], "big"), data[3]
        if ident != self.ident_number or not 0 <= new <= MAX_STATION_ADDRESS:
            return self._rs(tel)
        self._pending_address = new
        self.address_locked = bool(no_add_chg)
        return fdl.SHORT_ACK

    def _global_control(self, tel: fdl.Telegram, now: float) -> None:
        if len(tel.data) < 2 or tel.sa != self.master or self.state is DpState.WAIT_PRM:
            return
        command, group = tel.data[0], tel.data[1]
        if group and not group & self.group:
            return
        if command & GC_CLEAR_DATA:
            fail_safe(self.port, f"Global_Control Clear_Data from master {tel.sa}")
            self._apply(bytes(OUTPUT_SIZE))
        if command & (GC_SYNC | GC_UNSYNC):
            if not self.sync_enabled:
                self.not_supported = True
            else:
                if self._sync_pending is not None:
                    self._apply(self._sync_pending)
                    self._sync_pending = None
                self.sync_mode = not command & GC_UNSYNC
        if command & (GC_FREEZE | GC_UNFREEZE):
            if not self.freeze_enabled:
                self.not_supported = True
            elif command & GC_UNFREEZE:
                self.freeze_mode, self._frozen = False, None
            else:
                self.freeze_mode, self._frozen = True, self.port.input_bytes()

    # --- helpers -----------------------------------------------------------------------------
    def _apply(self, data: bytes) -> None:
        self.outputs = bytes(data)
        self.port.write_outputs(OutputImage.unpack(self.outputs))

    def _watch_diag(self, inputs: bytes) -> None:
        """002 §3.3 / 003 §4.2: a new diagnosis when a listed flag rises (0 → 1), and only then."""
        now_flags = SystemFlag(int(sysstate_from_bytes(inputs[2:6])) & int(DIAGNOSIS_FLAGS))
        if now_flags & ~self._sysstate:
            self._diag_pending = True
        self._sysstate = now_flags

    def _touch(self, now: float) -> None:
        """Restart the watchdog (when Set_Prm turned it on and the slave is parameterised)."""
        if self.watchdog_s is not None and self.state is not DpState.WAIT_PRM:
            self.watchdog_deadline = now + self.watchdog_s

    def _leave(self, reason: str, safe: bool) -> None:
        """Back to Wait_Prm; the gripper goes fail-safe when it was in Data_Exch."""
        if safe:
            log.warning("PROFIBUS DP: %s: leaving Data_Exch, gripper fail-safe", reason)
            fail_safe(self.port, reason)
        self.last_reason = reason
        self.state = DpState.WAIT_PRM
        self.watchdog_deadline = None
        self.sync_mode = self.freeze_mode = False
        self._sync_pending = self._frozen = None

    def _reply(self, tel: fdl.Telegram, data: bytes) -> bytes:
        return fdl.encode(tel.sa, self.address, fdl.RES_DL, data, dsap=tel.ssap, ssap=tel.dsap)

    def _rs(self, tel: fdl.Telegram) -> bytes:
        """"No service activated": the SAP is not open in this state (or not at all)."""
        self.stats.refused += 1
        return fdl.encode(tel.sa, self.address, fdl.RES_RS)


_SERVICES: dict[int, Callable[[DpSlave, fdl.Telegram, float], bytes | None]] = {
    SAP_SET_SLAVE_ADDRESS: DpSlave._set_slave_address,
    SAP_RD_INP: DpSlave._rd_inp,
    SAP_RD_OUTP: DpSlave._rd_outp,
    SAP_GLOBAL_CONTROL: DpSlave._global_control_srd,
    SAP_GET_CFG: DpSlave._get_cfg,
    SAP_SLAVE_DIAG: DpSlave._slave_diag,
    SAP_SET_PRM: DpSlave._set_prm,
    SAP_CHK_CFG: DpSlave._chk_cfg,
}

assert INPUT_SIZE == 12 and OUTPUT_SIZE == 8
