#!/usr/bin/env bash
# End-to-end tighten checks on the 12^3 box mask fixture (spacing 0.5, box of
# 6^3 voxels 3 voxels from the border): padding, geometry, sign conventions,
# upsampling, and a failed run leaving nothing behind.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
TI="$BIN/tighten"; VC="$BIN/volconv"; D="$SRC/tests/data"

# 1. r = 0.5 (one voxel): the box is 3 voxels from the border, r + 3 voxels are
#    needed, so the grid grows by one voxel a side; the centre is 1.5 deep.
"$TI" "$D/box_mask.nrrd" "$T/a.nrrd" --radius 0.5 --stats "$T/a.json" 2> "$T/a.err"
grep -q "padded by 1 voxels" "$T/a.err"
"$VC" --info "$T/a.nrrd" > "$T/ai.json"
"$TI" "$D/box_mask.nrrd" "$T/p.nrrd" --radius 0.5 --positive-inside -q
"$VC" --info "$T/p.nrrd" > "$T/pi.json"
"$TI" "$D/box_mask.nrrd" "$T/u.nrrd" --radius 0.5 --upsample 2 -q
"$VC" --info "$T/u.nrrd" > "$T/ui.json"
python3 - "$T/a.json" "$T/ai.json" "$T/pi.json" "$T/ui.json" <<'PY'
import json, sys
st, a, p, u = (json.load(open(f)) for f in sys.argv[1:5])
c = st["counts"]
assert c["pad"] == 1 and c["converged"] and c["inside_voxels"] == 216, c
assert a["type"] == "float" and a["dims"] == [14, 14, 14], a
assert all(abs(s - 0.5) < 1e-9 for s in a["spacing"]), a["spacing"]
assert all(abs(o + 0.5) < 1e-9 for o in a["origin"]), a["origin"]   # moved out by one voxel
assert abs(a["min"] + 1.25) < 0.02 and a["max"] > 2.0, (a["min"], a["max"])  # nodes nearest the centre: 2.5 voxels deep
assert abs(p["min"] + a["max"]) < 1e-6 and abs(p["max"] + a["min"]) < 1e-6, (p, a)  # exactly negated
assert u["dims"] == [27, 27, 27] and all(abs(s - 0.25) < 1e-9 for s in u["spacing"]), u
assert abs(u["min"] + 1.5) < 0.05, u["min"]  # the fine grid has a node at the centre
PY

# 2. Deterministic: one thread or two give the same bytes.
"$TI" "$D/box_mask.nrrd" "$T/t1.nrrd" --radius 0.5 --threads 1 -q
"$TI" "$D/box_mask.nrrd" "$T/t2.nrrd" --radius 0.5 --threads 2 -q
cmp "$T/t1.nrrd" "$T/t2.nrrd"

# 3. Messages: a run stopped at the step cap before a whole re-distancing
#    cycle says so without a cycle mean; a given radius with the automatic
#    upsampling prints no empty reason.
"$TI" "$D/box_mask.nrrd" "$T/c.nrrd" --radius 0.5 --iterations 2 --upsample auto 2> "$T/c.err"
grep -q "not converged after 2 steps (last move [0-9.]* voxels); raise --iterations" "$T/c.err" ||
  { echo "cap message:"; cat "$T/c.err"; exit 1; }
if grep -q "()" "$T/c.err"; then echo "empty reason:"; cat "$T/c.err"; exit 1; fi

# 4. --outside-band: the inside stays exact (the deepest value is the same),
#    the outside far from the box is close, and the stats say which band ran.
"$TI" "$D/box_mask.nrrd" "$T/ob.nrrd" --radius 0.5 --outside-band 0.5 --stats "$T/ob.json" -q
"$VC" --info "$T/ob.nrrd" > "$T/obi.json"
python3 - "$T/ai.json" "$T/obi.json" "$T/ob.json" <<'PY'
import json, sys
a, b, st = (json.load(open(f)) for f in sys.argv[1:4])
assert b["min"] == a["min"], (a["min"], b["min"])          # inside: exact
assert abs(b["max"] - a["max"]) <= 0.5, (a["max"], b["max"])  # far outside: within a voxel
assert st["parameters"]["outside_band"] == 0.5, st["parameters"]
PY
# The file says so (NRRD key pm_exact_positive), and the tools that would read farther out
# refuse it, naming the file: medialaxis --side both, and a sizing field band wider than 0.5.
grep -aq "^pm_exact_positive:=0.5$" "$T/ob.nrrd" || { echo "no pm_exact_positive key"; head -c 400 "$T/ob.nrrd"; exit 1; }
"$TI" "$D/box_mask.nrrd" "$T/exact.nrrd" --radius 0.5 -q
if grep -aq "pm_exact" "$T/exact.nrrd"; then echo "an exact distance has a pm_exact key"; exit 1; fi
"$BIN/medialaxis" "$T/exact.nrrd" "$T/ma.ply" --side both -q
if "$BIN/medialaxis" "$T/ob.nrrd" "$T/ma_ob.ply" --side both 2> "$T/ma.err"; then echo "banded distance accepted by --side both"; exit 1; fi
grep -q 'medialaxis: error: ".*ob.nrrd": .*outside the surface are exact only within 0.5 .*(tighten --outside-band), but --side both reads them' "$T/ma.err" ||
  { cat "$T/ma.err"; exit 1; }
[ ! -e "$T/ma_ob.ply" ] || { echo "refused medialaxis left an output"; exit 1; }
if "$BIN/sizingfield" --sdf "$T/ob.nrrd" --ma "$T/ma.ply" -o "$T/h_ob.nrrd" 2> "$T/sz.err"; then echo "banded distance accepted by sizingfield"; exit 1; fi
grep -q 'sizingfield: error: .*surface 1 (".*ob.nrrd"): its distances outside the surface are exact only within 0.5' "$T/sz.err" ||
  { cat "$T/sz.err"; exit 1; }

# 5. A failed run leaves no output and no temporary file.
mkdir "$T/fail"
if "$TI" "$D/grey_ramp.nrrd" "$T/fail/out.nrrd" --radius 1 2>/dev/null; then echo "grey input accepted"; exit 1; fi
if "$TI" "$D/box_mask.nrrd" "$T/fail/out.nrrd" --radius 0 2>/dev/null; then echo "radius 0 accepted"; exit 1; fi
[ -z "$(ls -A "$T/fail")" ] || { echo "left behind: $(ls -A "$T/fail")"; exit 1; }
echo "tighten workflow: ok"
