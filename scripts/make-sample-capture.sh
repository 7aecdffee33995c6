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
dumpcap -q -i lo -f "tcp port $port" -w "$tmp/cap.pcapng" 2> "$tmp/dumpcap.log" &
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
sleep 0.3
kill -INT "$dump"; wait "$dump" || true; dump=""
mkdir -p "$(dirname "$out")"
cp "$tmp/cap.pcapng" "$out"
echo "wrote $out (gripper port $port): wsg decode --port $port -f $out"
