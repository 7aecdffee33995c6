"""PROFINET IO (RT_CLASS_1, conformance class A): the virtual WSG as an IO device.

- :mod:`.dcp` — DCP: Identify, Get/Set NameOfStation and IP suite, Signal, Reset to factory
- :mod:`.rpc`, :mod:`.blocks`, :mod:`.ar` — DCE/RPC on UDP 34964: Connect, Read/Write, Control, Release
- :mod:`.rt` — cyclic RT frames (IOPS/IOCS, cycle counter, data status)
- :mod:`.ether` — ARP/IPv4/UDP for the device's own IP on the raw socket
- :mod:`.device` — the asyncio device on one interface (``wsg sim --profinet IFACE``)
- :mod:`.exchange` — PLC side (``profinet://IFACE/STATION``), needs the optional extra ``profinet``

All device-side code is pywsg's own (MIT); only :mod:`.exchange` imports profinet-py (GPL-3.0).
"""

from .device import BUS_NAME, ProfinetDevice, ProfinetError, serve_profinet

__all__ = ["BUS_NAME", "ProfinetDevice", "ProfinetError", "serve_profinet"]
