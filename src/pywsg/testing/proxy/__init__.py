"""A transparent tap between any WSG client and any WSG (real or virtual): ``wsg proxy``.

Bytes are forwarded unchanged and in order the moment they arrive (forwarding comes first, decoding
after), so the client and the gripper cannot tell the tap is there. Each complete frame is handed to
a :class:`~pywsg.capture.commlog.CommLog` (one decoded line per frame: time, TX/RX, command, status,
fields) and can be written to a pcapng file (readable by ``wsg decode -f``, ``wsg replay`` and
Wireshark) as synthetic IPv4 packets between the client's and the gripper's real addresses.

TCP: every client connection gets its own connection to the gripper (the gripper sees one client
per proxied client, as the command manual's single-client rule expects). A half-close passes
through both ways, and replies still in flight when a client goes are still captured (the gripper
side is kept :data:`CLOSE_GRACE_S` for them). UDP: datagrams from each client address go out from a
socket of their own (at most :data:`UDP_UPSTREAMS`, each closed after ``udp_idle`` s without
traffic); the gripper's replies go back to that client address. For a gripper that replies to a
fixed port (factory setting 1501) give ``?reply_port=1501`` in the target URL: one upstream socket
bound to that local port carries every client's datagrams, and a reply goes to the client whose
request with that command ID is the oldest unanswered one (else to the last client heard).

Bounds, like the sim's (docs/sim.md "Bounds"): at most :data:`HIGH_WATER` bytes wait to be sent to
either side before reading from the other pauses (backpressure both ways); decoding runs in chunks
on a task of its own (other clients never wait for a flood to be decoded), and reading pauses while
:data:`DECODE_BACKLOG` bytes wait for it. The capture is streamed to disk; the comm log gets at most
``log_rate`` frames a second (a line each second says what was left out; the pcapng has every byte),
and stream problems (bad checksums, garbage) are one summary note per chunk, so logging costs a
small factor of the traffic whatever it is sent.
"""

from ...capture.pcap import PcapWriter
from .capture import ProxyStats
from .decode import DECODE_BACKLOG
from .relay import HIGH_WATER, UDP_UPSTREAMS, Proxy

__all__ = ["DECODE_BACKLOG", "HIGH_WATER", "UDP_UPSTREAMS", "PcapWriter", "Proxy", "ProxyStats"]
