#!/usr/bin/env bash
# Large buffers on transparent huge pages (libcore/src/cli/run_tool.cpp): where
# the kernel gives huge pages to memory that asks for them (THP "madvise"), a
# tool sets glibc.malloc.hugetlb=1 (and glibc.malloc.arena_max=1) and
# executes itself again; --stats says
# "huge_pages" and counts minor page faults. Checked here: the flag follows
# the kernel's mode, PM_HUGE_PAGES=0 and a user's own hugetlb tunable are
# respected, other tunables are kept, the 16 MiB volumes of the run take far
# fewer page faults, the process keeps its pid and name, and the outputs are
# the same bytes either way.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
PY=/usr/bin/python3

mode=$(sed -n 's/.*\[\(.*\)\].*/\1/p' /sys/kernel/mm/transparent_hugepage/enabled 2>/dev/null || true)
echo "transparent huge pages: ${mode:-absent}"

# A 128^3 float volume (8 MiB; 16 MiB as double).
$PY - "$T/big.nrrd" <<'PY'
import array, sys
n = 128
with open(sys.argv[1], "wb") as f:
    f.write(b"NRRD0004\ntype: float\ndimension: 3\nsizes: %d %d %d\nspacings: 1 1 2\nencoding: raw\nendian: little\n\n"
            % (n, n, n))
    f.write(array.array("f", [1.0 + ((i * 7919) % 1000) / 100.0 for i in range(n ** 3)]).tobytes())
PY

run() {  # run NAME ENV... : volconv to double and gradlimit, stats in $T/NAME.*.json
  local name=$1; shift
  env "$@" "$BIN/volconv" "$T/big.nrrd" "$T/$name.nrrd" --type double --no-gzip --stats "$T/$name.v.json" -q
  env "$@" "$BIN/gradlimit" "$T/big.nrrd" "$T/$name.h.nrrd" --delta 0.3 --stats "$T/$name.g.json" -q
}
run default
run off PM_HUGE_PAGES=0
run user_off GLIBC_TUNABLES=glibc.malloc.hugetlb=0
run other GLIBC_TUNABLES=glibc.malloc.check=0

for name in off user_off other; do
  cmp "$T/default.nrrd" "$T/$name.nrrd"
  cmp "$T/default.h.nrrd" "$T/$name.h.nrrd"
done

# The process a tool executes again keeps its pid and its name (ps, top and
# pkill see "volconv", not "exe"), and its environment has the tunables
# (huge pages, and one malloc arena: glibc advises huge pages only there).
PM_TEST_HOLD=commit PM_TEST_HOLD_SECONDS=30 "$BIN/volconv" "$T/big.nrrd" "$T/held.nrrd" 2> "$T/held.log" &
pid=$!
for _ in $(seq 300); do grep -q "test hold at commit" "$T/held.log" && break; sleep 0.1; done
grep -q "test hold at commit" "$T/held.log"
comm=$(cat /proc/$pid/comm)
# (glibc parses GLIBC_TUNABLES in place: the environment block may show its
# ':' separators as NULs, so look at the tokens.)
tokens() { tr '\0:' '\n\n' < /proc/$1/environ | sed 's/^GLIBC_TUNABLES=//' | grep '^glibc\.' | sort | tr '\n' ' '; }
env_tokens=$(tokens $pid)
kill -TERM $pid; wait $pid || true
[ "$comm" = volconv ] || { echo "process name after re-exec: '$comm', expected volconv"; exit 1; }
if [ "$mode" = madvise ]; then
  [ "$env_tokens" = "glibc.malloc.arena_max=1 glibc.malloc.hugetlb=1 " ] ||
    { echo "GLIBC_TUNABLES of the running tool: '$env_tokens', expected hugetlb=1 and arena_max=1"; exit 1; }
fi
[ ! -e "$T/held.nrrd" ]
# A user's own tunables stay, and their arena_max is not overridden.
GLIBC_TUNABLES=glibc.malloc.arena_max=4 PM_TEST_HOLD=commit PM_TEST_HOLD_SECONDS=30 \
  "$BIN/volconv" "$T/big.nrrd" "$T/held.nrrd" 2> "$T/held.log" &
pid=$!
for _ in $(seq 300); do grep -q "test hold at commit" "$T/held.log" && break; sleep 0.1; done
tunables=$(tokens $pid)
kill -TERM $pid; wait $pid || true
if [ "$mode" = madvise ]; then
  [ "$tunables" = "glibc.malloc.arena_max=4 glibc.malloc.hugetlb=1 " ] ||
    { echo "GLIBC_TUNABLES of the running tool: '$tunables', expected the user's arena_max=4 kept"; exit 1; }
fi

# Under valgrind the tool does not execute itself again (valgrind would not
# follow it, and the user would lose the check without noticing).
if command -v valgrind > /dev/null; then
  valgrind --tool=none -q "$BIN/volconv" "$T/big.nrrd" "$T/vg.nrrd" --stats "$T/vg.json" -q
  $PY -c 'import json, sys; s = json.load(open(sys.argv[1])); assert s["huge_pages"] is (sys.argv[2] == "always"), s["huge_pages"]' \
    "$T/vg.json" "$mode"
  "$BIN/volconv" "$T/big.nrrd" "$T/novg.nrrd" -q
  cmp "$T/vg.nrrd" "$T/novg.nrrd"
fi

$PY - "$T" "$mode" <<'PY'
import json, sys
t, mode = sys.argv[1], sys.argv[2]
for tool in ("v", "g"):
    s = {n: json.load(open(f"{t}/{n}.{tool}.json")) for n in ("default", "off", "user_off", "other")}
    on = mode in ("madvise", "always")
    expect = {"default": on, "off": mode == "always", "user_off": mode == "always", "other": on}
    for n, want in expect.items():
        assert s[n]["huge_pages"] is want, (tool, n, s[n]["huge_pages"], want, mode)
    faults = {n: s[n]["minor_page_faults"] for n in s}
    print(tool, faults)
    if mode == "madvise":
        # Each 16 MiB buffer is 4096 small pages against 8 huge ones; loading the
        # libraries costs the same either way (about 2k faults).
        assert faults["default"] < 0.5 * faults["off"], faults
        assert faults["other"] < 0.5 * faults["off"], faults
print("huge pages ok")
PY
