#!/usr/bin/env bash
# make -f Makefile.pipeline materials (old name ch6) end to end on a tiny generated label map (a
# ball of radius 6 voxels split into two materials, in a background): every
# output is made, the interfaces are water-tight and the material surfaces
# closed and manifold. Uses multiparticles when it is built, else the stand-in.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
python3 - "$T/tiny.nrrd" <<'PY'
import struct, sys, math
n, c = 20, 9.5
vals = bytearray()
for k in range(n):
    for j in range(n):
        for i in range(n):
            vals.append(0 if math.dist((i, j, k), (c, c, c)) > 6 else (1 if i < 10 else 2))
with open(sys.argv[1], "wb") as o:
    o.write(f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: {n} {n} {n}\nspacings: 1 1 1\nencoding: raw\n\n".encode() + bytes(vals))
PY
SAMPLER=multiparticles
[ -x "$BIN/multiparticles" ] || SAMPLER=stand-in
make -s -f "$SRC/Makefile.pipeline" materials INPUT="$T/tiny.nrrd" OUT="$T/out" BIN="$BIN" R=1 SAMPLER=$SAMPLER \
  REQUIRE=watertight,manifold,labels_consistent 2> "$T/make.err" || { cat "$T/make.err" >&2; exit 1; }
for f in work/labels.nrrd work/morph.nrrd work/sdf_0.nrrd work/sdf_1.nrrd work/sdf_2.nrrd work/materials.spec \
         work/h.nrrd work/junction_seeds.ply points.ply interfaces.ply material_1.ply material_2.ply \
         quality.json interfaces.png interfaces_clipped.png points.png; do
  test -s "$T/out/$f" || { echo "missing $f" >&2; ls -R "$T/out" >&2; exit 1; }
done
# The old name still works (nothing to redo).
make -s -f "$SRC/Makefile.pipeline" ch6 INPUT="$T/tiny.nrrd" OUT="$T/out" BIN="$BIN" R=1 SAMPLER=$SAMPLER 2> /dev/null
python3 - "$T/out/quality.json" <<'PY'
import json, sys
q = json.load(open(sys.argv[1]))
i = q["interfaces"]
assert i["watertight"] and i["bad_edges"] == 0 and i["self_faces"] == 0, i
assert i["pairs"] == [[0, 1], [0, 2], [1, 2]], i["pairs"]
for l, m in q["materials"].items():
    t = m["topology"]
    assert t["watertight"] and t["manifold"] and t["components"] == 1, (l, t)
PY
# MA_SIDE=inside (the default): each material's inner medial axis only (their union is the
# interfaces' medial axis): the same inner points as with MA_SIDE=both, no outer ones, so the
# feature size and the sizing field can only grow.
make -s -f "$SRC/Makefile.pipeline" materials INPUT="$T/tiny.nrrd" OUT="$T/both" BIN="$BIN" R=1 SAMPLER=$SAMPLER \
  MA_SIDE=both 2> "$T/make_both.err" || { cat "$T/make_both.err" >&2; exit 1; }
for l in 0 1 2; do
  "$BIN/volconv" --info "$T/both/work/h.nrrd" > "$T/h_both.json"
  "$BIN/volconv" --info "$T/out/work/h.nrrd" > "$T/h_in.json"
  python3 - "$T/both/work/medialaxis_$l.json" "$T/out/work/medialaxis_$l.json" "$T/h_both.json" "$T/h_in.json" <<'PY'
import json, sys
both, inside, hb, hi = (json.load(open(p)) for p in sys.argv[1:5])
assert inside["counts"]["outer"] == 0, inside["counts"]
assert inside["counts"]["inner"] == both["counts"]["inner"], (inside["counts"], both["counts"])
assert hi["min"] >= hb["min"] - 1e-6 and hi["mean"] >= hb["mean"] - 1e-6, (hi, hb)
PY
done
python3 - "$T/both"/work/medialaxis_[012].json <<'PY'
import json, sys
assert sum(json.load(open(p))["counts"]["outer"] for p in sys.argv[1:]) > 0  # MA_SIDE=both does find outer points
PY
echo "ch6 pipeline passed ($SAMPLER)"
