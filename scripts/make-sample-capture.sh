#!/usr/bin/env bash
# Records a small Wireshark capture of a `wsg` session against a virtual gripper, for `wsg decode -f`:
#   ./scripts/make-sample-capture.sh [OUT.pcapng]      (default docs/examples/wsg-session.pcapng)
# Needs dumpcap (Debian: tshark) with capture rights on the loopback interface, and the venv (.venv)
# that ./scripts/demo.sh or ./scripts/test.sh creates. The session: home, move to 40 mm, read the
# width, an unknown command 90h (E_CMD_UNKNOWN), each command ending with the disconnect (07h).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out="$(realpath -m "${1:-$root/docs/examples/wsg-session.pcapng}")"
WSG="${WSG:-$root/.venv/bin/wsg}"
PY="$(dirname "$WSG")/python"
port="$("$PY" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
tmp="$(mktemp -d)"
cleanup() {
    [ -n "${dump:-}" ] && kill -INT "$dump" 2>/dev/null && wait "$dump" 2>/dev/null || true
    [ -n "${sim:-}" ] && kill -INT "$sim" 2>/dev/null && wait "$sim" 2>/dev/null || true
    rm -rf "$tmp"
}
trap cleanup EXIT
"$WSG" sim --tcp-port "$port" --udp-port off --serial off --web-port off > "$tmp/sim.log" 2>&1 &
sim=$!
# to stdout, dumpcap writes each packet at once (to a file it buffers): the file shows what is captured
dumpcap -q -i lo -f "tcp port $port" -w - > "$tmp/cap.pcapng" 2> "$tmp/dumpcap.log" &
dump=$!
for _ in $(seq 100); do     # both ready: the sim printed its banner, dumpcap wrote its file header
    if grep -q TCP "$tmp/sim.log" && [ -s "$tmp/cap.pcapng" ]; then break; fi
    kill -0 "$dump" 2>/dev/null || { cat "$tmp/dumpcap.log" >&2; exit 1; }
    sleep 0.1
done
sleep 0.3
url="tcp://127.0.0.1:$port"
"$WSG" --url "$url" home > /dev/null
"$WSG" --url "$url" move 40 --speed 400 > /dev/null
"$WSG" --url "$url" width > /dev/null
"$WSG" --url "$url" send 0x90 > /dev/null || true     # exit 1: the gripper answers E_CMD_UNKNOWN
# stop dumpcap once the last frames are written: the 90h reply (E_CMD_UNKNOWN) and the 07h after it
"$PY" - "$tmp/cap.pcapng" <<'PY' || { echo "dumpcap did not capture the session's last frames within 30 s" >&2; exit 1; }
import sys, time
from pywsg.protocol import Status, encode_frame
reply, bye = encode_frame(0x90, int(Status.E_CMD_UNKNOWN).to_bytes(2, "little")), encode_frame(0x07)
deadline = time.monotonic() + 30
while time.monotonic() < deadline:
    data = open(sys.argv[1], "rb").read()
    if reply in data and bye in data[data.find(reply):]:
        sys.exit(0)
    time.sleep(0.05)
sys.exit(1)
PY
kill -INT "$dump"; wait "$dump" || true; dump=""
mkdir -p "$(dirname "$out")"
cp "$tmp/cap.pcapng" "$out"
echo "wrote $out (gripper port $port): wsg decode --port $port -f $out"
