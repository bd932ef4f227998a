#!/usr/bin/env bash
# End-to-end morph checks: stencil sizes through the real tool, a Table 6.1
# style sequence with downsampling and voting on the Cleaver mickey label map,
# grey-value downsampling of the CGAL skull, and a failed run leaving nothing.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
MO="$BIN/morph"; VC="$BIN/volconv"

# 1. One voxel dilated once: 7, 19, 27 voxels.
for s in plus:7 ball:19 cube:27; do
  "$MO" "$SRC/tests/data/onevoxel.nrrd" "$T/d.nrrd" --op dilate --stencil "${s%%:*}" --stats "$T/d.json" -q
  "$VC" --info "$T/d.nrrd" > "$T/di.json"
  python3 - "$T/d.json" "$T/di.json" "${s##*:}" <<'PY'
import json, sys
d, info = (json.load(open(p)) for p in sys.argv[1:3])
n = int(sys.argv[3])
want = {"0": 27 - n, "1": n} if n < 27 else {"1": 27}
assert d["counts"]["labels_after"] == want, d["counts"]
assert info["type"] == "float" and abs(info["mean"] - n / 27) < 1e-9, info
PY
done

# 2. Mickey: close/open every material, downsample by 2, vote.
M="$SRC/data/cleaver-mickey/mickey.nrrd"
"$MO" "$M" "$T/m.nrrd" --labels 2-5 --ops "close:f2,open:f1; 5=close:ball" --downsample 2 --vote --stats "$T/m.json" -q
"$VC" --info "$T/m.nrrd" > "$T/mi.json"
python3 - "$T/m.json" "$T/mi.json" <<'PY'
import json, sys
st, info = (json.load(open(p)) for p in sys.argv[1:3])
assert info["dims"] == [32, 32, 32], info["dims"]            # ceil(63 / 2)
assert all(abs(s - 2) < 1e-9 for s in info["spacing"]), info["spacing"]
assert all(abs(o - 0.5) < 1e-9 for o in info["origin"]), info["origin"]  # centre of the first 2^3 block
assert info["type"] == "uint16", info["type"]
L = info["labels"]
assert sum(L.values()) == 32 ** 3 and "0" not in L, L      # voting left nothing empty
for l in ("1", "2", "3", "4"):
    assert L.get(l, 0) > 0, (l, L)
before = st["counts"]["labels_before"]
assert before == {"1": 232028, "2": 16348, "3": 822, "4": 822, "5": 27}, before
assert st["counts"]["labels_after"] == L, (st["counts"]["labels_after"], L)
# Big materials keep about their share of the volume (63^3 -> 32^3 voxels).
r = 32 ** 3 / 63 ** 3
assert abs(L["1"] - 232028 * r) < 0.02 * 232028 * r, L
assert abs(L["2"] - 16348 * r) < 0.15 * 16348 * r, L
PY

# --labels all: every label present (mickey has no 0: labels 1-5), the same file as the list.
"$MO" "$M" "$T/all.nrrd" --labels all --ops "close:f2,open:f1" --downsample 2 --vote -q
"$MO" "$M" "$T/list.nrrd" --labels 1-5 --ops "close:f2,open:f1" --downsample 2 --vote -q
cmp "$T/all.nrrd" "$T/list.nrrd"

# 3. Grey values: block mean.
"$MO" "$SRC/data/cgal-skull/skull_2.9.inr" "$T/g.nrrd" --grey --downsample 2 -q
"$VC" --info "$SRC/data/cgal-skull/skull_2.9.inr" > "$T/g0.json"
"$VC" --info "$T/g.nrrd" > "$T/g1.json"
python3 - "$T/g0.json" "$T/g1.json" <<'PY'
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
assert b["dims"] == [32, 32, 32], b["dims"]
for x, y in zip(a["spacing"], b["spacing"]):
    assert abs(2 * x - y) < 1e-4, (a["spacing"], b["spacing"])
assert abs(a["mean"] - b["mean"]) < 1e-4 * max(1, abs(a["mean"])), (a["mean"], b["mean"])  # 64 = 2 * 32: no partial blocks
assert a["min"] <= b["min"] and b["max"] <= a["max"]
PY

# 3b. Small components: mickey's label 5 is one 27-voxel cube, below 28 voxels; removing it would
#     erase the material, so its largest component stays, listed in `kept` with a warning.
"$MO" "$M" "$T/c.nrrd" --min-component 28 --stats "$T/c.json" 2> "$T/c.err"
grep -q "morph: warning: label 5: .*kept" "$T/c.err" || { echo "no warning for label 5: $(cat "$T/c.err")"; exit 1; }
python3 - "$T/c.json" <<'PY'
import json, sys
st = json.load(open(sys.argv[1]))["counts"]
assert st["kept"] == [{"label": 5, "stage": "min_component", "voxels": 27}], st
assert st["labels_after"] == st["labels_before"], st
assert sum(st["labels_after"].values()) == 63 ** 3, st
PY

# gzip by default; --no-gzip (the pipelines' intermediates) writes the same voxels raw.
"$MO" "$M" "$T/gz.nrrd" --labels all --ops "close:ball,open:ball" -q
"$MO" "$M" "$T/raw.nrrd" --labels all --ops "close:ball,open:ball" --no-gzip -q
/usr/bin/python3 "$SRC/tests/cli/same_voxels.py" "$T/gz.nrrd" "$T/raw.nrrd" gzip raw

# 4. A failed run leaves no output and no temporary file.
mkdir "$T/fail"
if "$MO" "$M" "$T/fail/out.nrrd" --op open --labels 9 2>/dev/null; then echo "absent label accepted"; exit 1; fi
[ -z "$(ls -A "$T/fail")" ] || { echo "left behind: $(ls -A "$T/fail")"; exit 1; }
echo "morph workflow: ok"
