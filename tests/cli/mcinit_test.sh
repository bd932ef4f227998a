#!/usr/bin/env bash
# End-to-end mcinit checks: seeds of the CGAL skull at its isovalue (PLY with
# normals and component ids; decimation keeps every component), junction seeds
# of the Cleaver mickey label map, and a failed run leaving nothing.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
MC="$BIN/mcinit"
S="$SRC/data/cgal-skull/skull_2.9.inr"

"$MC" "$S" "$T/s.ply" --iso 2.9 --kernel mix --stats "$T/s.json" -q
"$MC" "$S" "$T/d.ply" --iso 2.9 --kernel mix --decimate 2 --stats "$T/d.json" -q
"$MC" "$SRC/data/cleaver-mickey/mickey.nrrd" "$T/j.ply" --junctions --stats "$T/j.json" -q
python3 - "$T" <<'PY'
import json, sys
T = sys.argv[1]
def header(p):
    raw = open(p, "rb").read()
    return raw[: raw.index(b"end_header")].decode()
s, d, j = (json.load(open(f"{T}/{n}.json")) for n in "sdj")
hs = header(f"{T}/s.ply")
for prop in ("x", "nx", "component"):
    assert f" {prop}\n" in hs, hs
cs, cd = s["counts"], d["counts"]
assert f"element vertex {cs['seeds']}\n" in hs, hs
assert cs["seeds"] == cs["crossings"] > 1000, cs
assert cs["projected"] > 0.99 * cs["seeds"] and cs["max_residual"] < 1e-3, cs
assert cs["components"] >= 1 and cd["components"] == cs["components"], (cs, cd)
assert cd["crossings"] == cs["crossings"] and cd["seeds"] < cs["seeds"] / 2, (cs, cd)
hj = header(f"{T}/j.ply")
for prop in ("junction", "label_a", "label_b", "label_c", "label_d"):
    assert f" {prop}\n" in hj, hj
cj = j["counts"]
assert "1-2" in cj["pairs"] and cj["triples"] > 0, cj
assert cj["seeds"] == sum(cj["pairs"].values()) + cj["triples"] + cj["quadruples"], cj
PY

mkdir "$T/fail"
if "$MC" "$S" "$T/fail/out.ply" --iso 99 2>/dev/null; then echo "isovalue outside the range accepted"; exit 1; fi
[ -z "$(ls -A "$T/fail")" ] || { echo "left behind: $(ls -A "$T/fail")"; exit 1; }
echo "mcinit workflow: ok"
