#!/usr/bin/env bash
# End-to-end medialaxis checks: the tightened box fixture (a convex shape: inner
# medial axis only, within the box, distances up to its half-width), the grey
# route (--iso, --sdf-out) on the box mask and on the CGAL skull, and a failed
# run leaving nothing behind.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
MA="$BIN/medialaxis"; VC="$BIN/volconv"; D="$SRC/tests/data"
ply_distances() {  # print "x y z distance" per vertex of a binary little-endian PLY
  python3 - "$1" <<'PY'
import struct, sys
f = open(sys.argv[1], "rb"); props = []; n = 0; fmt = ""
while True:
    l = f.readline().decode().strip()
    if l.startswith("element vertex"): n = int(l.split()[2])
    if l.startswith("property"): props.append(l.split())
    if l == "end_header": break
fmt = "<" + "".join({"float": "f", "double": "d"}[p[1]] for p in props)
names = [p[2] for p in props]
for _ in range(n):
    v = dict(zip(names, struct.unpack(fmt, f.read(struct.calcsize(fmt)))))
    print(v["x"], v["y"], v["z"], v["distance"])
PY
}

# 1. Tightened box (fixture box_sdf.nrrd: box [1.25, 4.25]^3 world, r = 0.5).
"$MA" "$D/box_sdf.nrrd" "$T/b.ply" --volume "$T/b.nrrd" --stats "$T/b.json" -q
"$VC" --info "$T/b.nrrd" > "$T/bi.json"
ply_distances "$T/b.ply" > "$T/b.txt"
python3 - "$T/b.json" "$T/bi.json" "$T/b.txt" <<'PY'
import json, sys
st, vi = (json.load(open(p)) for p in sys.argv[1:3])
c = st["counts"]
assert c["points"] >= 20 and c["outer"] == 0 and c["inner"] == c["points"], c
assert vi["type"] == "uint8" and vi["dims"] == [14, 14, 14] and 0 < vi["labels"]["1"] <= c["points"], vi
pts = [list(map(float, l.split())) for l in open(sys.argv[3])]
assert len(pts) == c["points"]
for x, y, z, d in pts:
    assert all(1.25 < t < 4.25 for t in (x, y, z)), (x, y, z)
    # On the inner medial axis of the box the distance to the surface is the
    # smallest distance to a face (within half a voxel: faces are rounded by r).
    face = min(x - 1.25, 4.25 - x, y - 1.25, 4.25 - y, z - 1.25, 4.25 - z)
    assert 0 < d <= 1.5 + 1e-6 and abs(d - face) < 0.25, (x, y, z, d, face)
PY

# 2. Grey route: the box mask at iso 0.5, inside above, writes the distance it used.
"$MA" "$D/box_mask.nrrd" "$T/g.ply" --iso 0.5 --inside above --sdf-out "$T/g.nrrd" --stats "$T/g.json" -q
"$VC" --info "$T/g.nrrd" > "$T/gi.json"
python3 - "$T/g.json" "$T/gi.json" <<'PY'
import json, sys
st, gi = (json.load(open(p)) for p in sys.argv[1:3])
assert st["counts"]["points"] > 0 and st["counts"]["outer"] == 0, st["counts"]
assert gi["type"] == "float" and gi["dims"] == [12, 12, 12], gi
assert abs(gi["min"] + 1.25) < 1e-5, gi["min"]   # nodes nearest the centre: 2.5 voxels of 0.5 deep
PY

# 3. The CGAL skull (grey CT-like field, bone above 2.9), when the sample data are present.
S="$SRC/data/cgal-skull/skull_2.9.inr"
if [ -f "$S" ]; then
  "$MA" "$S" "$T/s.ply" --iso 2.9 --inside above --sdf-out "$T/s.nrrd" --stats "$T/s.json" -q
  python3 - "$T/s.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))["counts"]
assert c["inner"] > 1000 and c["outer"] > 1000, c   # a shell: medial sheet inside the bone, and outside
PY
  # Deterministic on a grid large enough to be split between threads.
  "$MA" "$T/s.nrrd" "$T/s1.ply" --threads 1 -q
  cmp "$T/s.ply" "$T/s1.ply"
  # --lfs-only (the pipelines' setting): the bone is thin and stays inside the grid, so
  # the far medial axis outside it goes, and the sizing field is the same, bit for bit.
  "$MA" "$T/s.nrrd" "$T/sl.ply" --lfs-only --stats "$T/sl.json" -q
  python3 - "$T/s.json" "$T/sl.json" <<'PY'
import json, sys
full, near = (json.load(open(p)) for p in sys.argv[1:3])
b = near["parameters"]["max_distance"]
assert isinstance(b, float) and 0 < b < 60, b        # twice the bone's depth plus two voxel diagonals
assert near["counts"]["inner"] == full["counts"]["inner"], (near["counts"], full["counts"])
assert near["counts"]["outer"] < 0.8 * full["counts"]["outer"], (near["counts"], full["counts"])
assert near["counts"]["nodes_refined"] < full["counts"]["nodes_refined"]
PY
  "$BIN/sizingfield" --sdf "$T/s.nrrd" --ma "$T/s.ply" -o "$T/h_all.nrrd" --eps 0.5 -q
  "$BIN/sizingfield" --sdf "$T/s.nrrd" --ma "$T/sl.ply" -o "$T/h_lfs.nrrd" --eps 0.5 -q
  cmp "$T/h_all.nrrd" "$T/h_lfs.nrrd"
fi

# 4. Deterministic: one thread or two give the same points in the same order.
"$MA" "$D/box_sdf.nrrd" "$T/t1.ply" --threads 1 -q
"$MA" "$D/box_sdf.nrrd" "$T/t2.ply" --threads 2 -q
cmp "$T/t1.ply" "$T/t2.ply"

# 5. A failed run leaves no output and no temporary file.
mkdir "$T/fail"
if "$MA" "$D/box_mask.nrrd" "$T/fail/o.ply" --volume "$T/fail/o.nrrd" 2>/dev/null; then echo "mask accepted"; exit 1; fi
if "$MA" "$D/grey_ramp.nrrd" "$T/fail/o.ply" --iso 100 --sdf-out "$T/fail/s.nrrd" 2>/dev/null; then echo "iso 100 accepted"; exit 1; fi
[ -z "$(ls -A "$T/fail")" ] || { echo "left behind: $(ls -A "$T/fail")"; exit 1; }
echo "medialaxis workflow: ok"
