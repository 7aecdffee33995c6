#!/usr/bin/env bash
# The suite on a busy machine: a fresh clone of this checkout's HEAD, then ./scripts/test.sh three times in a
# row while two busy-loop CPU hogs run (one per core of a 2-core machine). Prints pass/fail and wall time
# per run and exits non-zero when any run failed. The clone sits in a temporary directory that also holds
# `shared` (a link to the manuals beside this checkout, ../shared), as CI has them; run 1 includes
# creating the clone's .venv. Logs stay in the directory printed at the end.
#
#   scripts/busy-test.sh            RUNS=3 HOGS=2 by default; e.g. RUNS=1 HOGS=0 for a quiet single run
set -uo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
runs=${RUNS:-3}
hogs=${HOGS:-2}
work=$(mktemp -d "${TMPDIR:-/tmp}/pywsg-busy.XXXXXX")
logs=$work/logs
mkdir -p "$logs"
hog_pids=()
cleanup() {
    for pid in "${hog_pids[@]}"; do kill "$pid" 2>/dev/null; done
    wait "${hog_pids[@]}" 2>/dev/null
    rm -rf "$work/pywsg"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

if [ -d "$repo/../shared" ]; then
    ln -s "$(cd "$repo/../shared" && pwd)" "$work/shared"
fi
git clone -q "$repo" "$work/pywsg" || exit 1
git -C "$work/pywsg" checkout -q --detach "$(git -C "$repo" rev-parse HEAD)" || exit 1
echo "clone of $(git -C "$work/pywsg" log -1 --format='%h %s') in $work/pywsg"

for _ in $(seq "$hogs"); do
    ( while :; do :; done ) &
    hog_pids+=($!)
done
echo "$hogs busy-loop CPU hog(s) running (pids ${hog_pids[*]:-none}); $(nproc) cores; load average $(cut -d' ' -f1-3 /proc/loadavg)"

failed=0
summary=()
for i in $(seq "$runs"); do
    start=$(date +%s)
    (cd "$work/pywsg" && ./scripts/test.sh) >"$logs/run-$i.log" 2>&1
    code=$?
    wall=$(( $(date +%s) - start ))
    if [ $code -eq 0 ]; then verdict=pass; else verdict="FAIL (exit $code)"; failed=1; fi
    line=$(printf 'run %d: %-15s wall %dm%02ds  load average %s  (%s)' "$i" "$verdict" $((wall / 60)) $((wall % 60)) \
        "$(cut -d' ' -f1-3 /proc/loadavg)" "$(grep -E '(passed|failed|error).* in [0-9.]+s' "$logs/run-$i.log" | head -n 1 | tr -d '=' | xargs)")
    echo "$line"
    summary+=("$line")
done
echo "--- $runs run(s), $hogs hog(s), $(date -u +%Y-%m-%dT%H:%MZ); logs in $logs"
printf '%s\n' "${summary[@]}"
exit $failed
