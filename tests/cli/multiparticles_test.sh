#!/usr/bin/env bash
# multiparticles on the 16^3 three-wedge label map (tests/data/wedges3.nrrd):
# every level runs, the PLY carries the documented properties, runs are
# bit-identical for a fixed seed whatever the thread count, seeds from
# `mcinit --junctions` chain in, and bad input fails with a clear message.
# Usage: multiparticles_test.sh BIN_DIR SOURCE_DIR
set -euo pipefail
BIN=$1
SRC=$2
D=$SRC/tests/data
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
MP=$BIN/multiparticles
fail() { echo "FAIL: $*" >&2; exit 1; }

# 1. Default seeds (argmax grid of the materials), stats on stdout.
"$MP" --materials "$D/wedges3.nrrd" --spacing 2.5 -o "$T/a.ply" --stats "$T/a.json" -q --threads 1 --seed 7
python3 - "$T/a.json" "$T/a.ply" <<'EOF'
import json, sys
st = json.load(open(sys.argv[1]))
lv = st["levels"]
assert lv["curves"]["cells"] == 1, lv
assert lv["curves"]["particles"] >= 4, lv
assert lv["surfaces"]["cells"] == 3, lv
assert lv["surfaces"]["particles"] > 20, lv
assert lv["curves"]["converged"] and lv["surfaces"]["converged"], lv
assert st["max_residual"] < 1e-4, st["max_residual"]
hdr = open(sys.argv[2], "rb").read(2000).split(b"end_header")[0].decode()
for prop in ["x", "y", "z", "nx", "ny", "nz", "junction", "label_a", "label_b", "label_c", "label_d", "spacing",
             "energy", "residual"]:
    assert (" " + prop + "\n") in hdr, (prop, hdr)
EOF

# 2. Deterministic: same seed, another thread count -> identical file.
"$MP" --materials "$D/wedges3.nrrd" --spacing 2.5 -o "$T/b.ply" -q --threads 2 --seed 7
cmp "$T/a.ply" "$T/b.ply" || fail "runs with 1 and 2 threads differ"

# 3. Seeds from mcinit --junctions.
"$BIN/mcinit" "$D/wedges3.nrrd" "$T/seeds.ply" --junctions -q
"$MP" --materials "$D/wedges3.nrrd" --seeds "$T/seeds.ply" --spacing 2.5 -o "$T/c.ply" --stats - -q \
  | grep -q '"surfaces"' || fail "no stats with --seeds"

# 4. Bad input: exit 1 and a clear message.
expect_fail() {  # regex, args...
  local re=$1; shift
  set +e
  out=$("$MP" "$@" 2>&1); rc=$?
  set -e
  [ $rc -eq 1 ] || [ $rc -eq 2 ] || fail "exit $rc for $*: $out"
  echo "$out" | grep -Eq "$re" || fail "message '$out' does not match '$re'"
  [ ! -e "$T/bad.ply" ] || fail "a failed run left $T/bad.ply"
}
expect_fail "multiparticles: error: .*(1 material|at least 2|fewer than 2|single|one label|only one)" \
  --materials "$D/zeros.nrrd" --spacing 1 -o "$T/bad.ply"
expect_fail "multiparticles: error: .*onevoxel.nrrd.*h = 0" \
  --materials "$D/wedges3.nrrd" --sizing "$D/onevoxel.nrrd" -o "$T/bad.ply"
# A valid sizing field (h = 1) on a box that covers only a corner of the wedges (x, y, z <= 5):
# most junction seeds lie outside it, where it used to give its smallest h without a word.
python3 - "$T/corner_h.nrrd" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("NRRD0004\ntype: float\ndimension: 3\nsizes: 6 6 6\nspacings: 1 1 1\nencoding: ascii\n\n")
    f.write(" ".join(["1"] * 216) + "\n")
PY
expect_fail "multiparticles: error: sizing field .*corner_h.nrrd.* does not cover the junctions: [0-9]+ of [0-9]+ seeds lie outside its box" \
  --materials "$D/wedges3.nrrd" --sizing "$T/corner_h.nrrd" -o "$T/bad.ply"
printf 'ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty float junction\nproperty float label_a\nproperty float label_b\nproperty float label_c\nproperty float label_d\nend_header\nnan 1 1 2 1 2 -1 -1\n' > "$T/nan.ply"
expect_fail "multiparticles: error: .*nan.ply.*not finite" \
  --materials "$D/wedges3.nrrd" --seeds "$T/nan.ply" --spacing 2 -o "$T/bad.ply"
# Labels that never touch the materials' labels: the one-voxel map has labels 0|1, the wedges 1, 2, 3.
expect_fail "multiparticles: error: no material interface found" \
  --materials "$D/wedges3.nrrd" --labels "$D/onevoxel.nrrd" --spacing 2 -o "$T/bad.ply"
expect_fail "multiparticles: usage error: spacing must be > 0" \
  --materials "$D/wedges3.nrrd" --spacing 0 -o "$T/bad.ply"
expect_fail "multiparticles: usage error: --spacing S" --materials "$D/wedges3.nrrd" -o "$T/bad.ply"
echo "multiparticles CLI: ok"
