"""PROFINET IO in a container (docs/container.md, "Fieldbus in a container"): the image's `wsg sim
--profinet eth0` in a network namespace the test makes (the container joins it, as it would join a macvlan
network), profinet-py as the IO controller outside the container, in a second namespace at the other end
of the veth pair (tests/fieldbus/profinet/conftest.py)."""

from __future__ import annotations

from ..fieldbus.profinet.conftest import DEVICE_IP, STATION, WSG, Wire, wire
from .conftest import podman, pytestmark, unique

__all__ = ["pytestmark", "wire"]


def test_profinet_device_in_a_container_answers_a_controller_outside(image: str, wire: Wire) -> None:
    name = unique("profinet")
    try:
        # root in the container and NET_RAW: a raw Ethernet socket (the image's user binds ports only)
        podman("run", "-d", "--name", name, "--network", f"ns:/run/netns/{wire.device_ns}",
               "--user", "root", "--cap-add", "NET_RAW", "-e", "WSG_SIM_TCP_PORT=off", "-e", "WSG_SIM_UDP_PORT=off",
               "-e", "WSG_SIM_WEB_PORT=off", image, "--profinet", wire.iface, "--profinet-name", STATION,
               "--profinet-ip", f"{DEVICE_IP}/24", "--part", "22")
        found = wire.controller("identify", STATION)
        assert found["name"] == STATION and found["ip"] == DEVICE_IP, found
        assert (found["vendor_id"], found["device_id"]) == (0x02A2, 0x0001)   # 002 §2.2
        # 002 App. D's gripping cycle as the user runs it, wsg plc-demo over profinet:// (an AR from pywsg's
        # GSDML), against the container's raw socket
        # a 128 ms cycle: this test is about the container's raw socket, not the shortest cycle a loaded
        # machine holds (benchmarks/bench_profinet.py)
        url = f"profinet://{wire.iface}/{STATION}?cycle_ms=128"
        done = wire.controller(argv=[*WSG, "plc-demo", "--url", url, "--cycles", "1", "--json"], timeout=90)
        assert done["event"] == "done" and done["ok"] is True, done
        assert done["cycles"] == 1 and done["holds"] == 1 and done["errors"] == 0, done
        assert "profinet" in podman("logs", name).stdout
    finally:
        podman("rm", "-f", "-v", name, check=False)
