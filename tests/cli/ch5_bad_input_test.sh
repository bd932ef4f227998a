#!/usr/bin/env bash
# Chapter 5 bad input: empty and all-inside volumes stop the pipeline before any
# stage with a clear message; particles that miss a surface component are caught
# by meshstats --seeds (the marching-cubes seeds know every component); TetGen
# failures (coplanar or too few particles) exit 1 and leave no output.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
expect() {  # expect CODE REGEX cmd...
  local code=$1 re=$2; shift 2
  set +e; msg=$("$@" 2>&1); rc=$?; set -e
  [ $rc -eq "$code" ] || { echo "expected exit $code, got $rc: $*: $msg"; exit 1; }
  echo "$msg" | grep -Eq "$re" || { echo "unexpected message for $*: $msg"; exit 1; }
}
MK=(make -s -f "$SRC/Makefile.pipeline" surface BIN="$BIN")
# make exits 2 when a recipe fails; the message is the pipeline's.
expect 2 "has the value 0 everywhere \(an empty or all-inside volume\): no surface to mesh" \
  "${MK[@]}" INPUT="$SRC/tests/data/empty_mask.nrrd" OUT="$T/empty"
python3 -c "
import sys
sys.stdout.write('NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: ascii\n\n' + ' '.join(['1'] * 64) + '\n')" > "$T/full.nrrd"
expect 2 "has the value 1 everywhere" "${MK[@]}" INPUT="$T/full.nrrd" OUT="$T/full"
expect 2 "isovalue ISO=100 is outside the value range \[0, 63\]" \
  "${MK[@]}" INPUT="$SRC/tests/data/grey_ramp.nrrd" ISO=100 OUT="$T/ramp"
# a NRRD that volconv cannot read (its data cut short): volconv's own error, naming the file
printf 'NRRD0004\ntype: uint8\ndimension: 3\nsizes: 24 24 24\nencoding: raw\n\nxxxx' > "$T/cut.nrrd"
expect 2 "volconv: error: .*cut.nrrd.: truncated: expected 13824 bytes" "${MK[@]}" INPUT="$T/cut.nrrd" OUT="$T/cut"
[ ! -e "$T/empty" ] && [ ! -e "$T/full" ] && [ ! -e "$T/ramp" ] && [ ! -e "$T/cut" ] ||
  { echo "a refused input left an OUT folder"; exit 1; }

# Two separate balls; particles seeded on the first ball only sample one component.
python3 - "$T" <<'PY'
import sys
n, h = 24, 0.1
def write(path, both):
    vals = []
    for k in range(n):
        for j in range(n):
            for i in range(n):
                x, y, z = i * h, j * h, k * h
                d1 = ((x - 0.6) ** 2 + (y - 1.15) ** 2 + (z - 1.15) ** 2) ** 0.5 - 0.4
                d2 = ((x - 1.7) ** 2 + (y - 1.15) ** 2 + (z - 1.15) ** 2) ** 0.5 - 0.4
                vals.append(min(d1, d2) if both else d1)
    with open(path, "w") as f:
        f.write(f"NRRD0004\ntype: float\ndimension: 3\nsizes: {n} {n} {n}\nspacings: {h} {h} {h}\nencoding: ascii\n\n")
        f.write("\n".join(f"{v:.6g}" for v in vals) + "\n")
write(sys.argv[1] + "/two.nrrd", True)
write(sys.argv[1] + "/one.nrrd", False)
PY
"$BIN/mcinit" "$T/two.nrrd" "$T/seeds_two.ply" --iso 0 -q
"$BIN/mcinit" "$T/one.nrrd" "$T/seeds_one.ply" --iso 0 -q
"$BIN/particles" -i "$T/two.nrrd" --iso 0 --spacing 0.12 --init "$T/seeds_one.ply" -o "$T/p.ply" -q --tolerance 1e-3
"$BIN/tetlabel" "$T/p.ply" -i "$T/two.nrrd" --iso 0 -o "$T/surface.ply" -q
expect 1 "meshstats: error: .*surface.ply.*misses components of the isosurface .*component 1 \([0-9]+ seeds, around \(1\.7" \
  "$BIN/meshstats" "$T/surface.ply" -i "$T/two.nrrd" --iso 0 --seeds "$T/seeds_two.ply" -o "$T/q.json"
[ ! -e "$T/q.json" ] || true
# Seeded with both balls' seeds, both components are sampled (single level: at
# the coarse levels of coarse-to-fine, 2s = 0.24 on balls of radius 0.4, population
# control currently deletes every particle of the second ball; meshstats catches it).
"$BIN/particles" -i "$T/two.nrrd" --iso 0 --spacing 0.12 --init "$T/seeds_two.ply" -o "$T/p2.ply" -q --tolerance 1e-3 \
  --no-coarse-to-fine
"$BIN/tetlabel" "$T/p2.ply" -i "$T/two.nrrd" --iso 0 -o "$T/surface2.ply" -q
"$BIN/meshstats" "$T/surface2.ply" -i "$T/two.nrrd" --iso 0 --seeds "$T/seeds_two.ply" --require watertight,components=2 -q

# TetGen failures: coplanar particles, too few particles.
printf 'ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n0.5 0.3 0\n' > "$T/flat.ply"
expect 1 "tetlabel: error: .*flat.ply.*coplanar" "$BIN/tetlabel" "$T/flat.ply" -i "$T/two.nrrd" --iso 0 -o "$T/f.ply"
expect 1 "tetlabel: error: .*three_points.ply.*3 points; expected at least 4" \
  "$BIN/tetlabel" "$SRC/tests/data/three_points.ply" -i "$T/two.nrrd" --iso 0 -o "$T/f.ply"
[ ! -e "$T/f.ply" ] || { echo "a failed tetlabel left its output"; exit 1; }
echo "ch5 bad input: ok"
