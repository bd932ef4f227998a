#!/usr/bin/env bash
# Issue 21: a 2x2x2 label map with five labels meshes with the defaults of
# `make -f Makefile.pipeline materials` (no MORPH_OPS, UPSAMPLE, PAD or R given): the
# morphology would erase every material and keeps them instead (with a warning), tighten
# upsamples the tiny volume (K = 8) and uses a radius of one fine voxel, and the interfaces
# come out water-tight with every material closed and manifold. Checks the OUT / OUT/work layout, the
# per-stage lines and the one-line summary too.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
# Labels 0 (four voxels, z = 0) and 1..4 (one voxel each, z = 1), spacing 1 mm.
printf 'NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nspacings: 1 1 1\nencoding: ascii\n\n0 0 0 0 1 2 3 4\n' > "$T/tiny.nrrd"
SAMPLER=multiparticles
[ -x "$BIN/multiparticles" ] || SAMPLER=stand-in
make -s -f "$SRC/Makefile.pipeline" materials INPUT="$T/tiny.nrrd" OUT="$T/out" BIN="$BIN" SAMPLER=$SAMPLER \
  REQUIRE=watertight,manifold,labels_consistent 2> "$T/make.err" || { cat "$T/make.err" >&2; exit 1; }
cat "$T/make.err"
# One line per stage with its seconds, the kept-material warnings, the summary last.
grep -Eq '^materials: tighten +[0-9]+\.[0-9] s$' "$T/make.err" || { echo "no tighten stage line" >&2; exit 1; }
grep -q 'morph: warning: label 4: the morphology would erase it; kept 1 voxel' "$T/make.err" ||
  { echo "no kept-material warning" >&2; exit 1; }
tail -n 1 "$T/make.err" | grep -Eq '^materials: [0-9]+ vertices, 5 materials, [0-9]+ interfaces, rr min [0-9.]+ mean [0-9.]+, watertight, creases' ||
  { echo "bad summary line" >&2; exit 1; }
# Results in OUT, intermediates in OUT/work.
# (label 0 also stands for the outside of the volume: its surface is not written as a file)
for f in points.ply interfaces.ply quality.json interfaces.png interfaces_clipped.png points.png \
         material_1.ply material_2.ply material_3.ply material_4.ply; do
  test -s "$T/out/$f" || { echo "missing OUT/$f" >&2; ls "$T/out" >&2; exit 1; }
done
for f in labels.nrrd morph.nrrd sdf_0.nrrd sdf_4.nrrd materials.spec h.nrrd junction_seeds.ply tighten.json logs/tighten.log; do
  test -s "$T/out/work/$f" || { echo "missing OUT/work/$f" >&2; ls "$T/out/work" >&2; exit 1; }
done
extra=$(cd "$T/out" && ls | grep -Ev '^(work|points\.ply|interfaces\.ply|volume\.mesh|quality\.json|interfaces\.png|interfaces_clipped\.png|points\.png|material_[0-9]+\.ply)$' || true)
[ -z "$extra" ] || { echo "intermediates in OUT: $extra" >&2; exit 1; }
python3 - "$T/out" <<'PY'
import json, sys
out = sys.argv[1]
t = json.load(open(out + "/work/tighten.json"))["parameters"]
assert t["upsample"] == 8 and abs(t["radius"] - 0.125) < 1e-12, t   # 1 mm / 8
q = json.load(open(out + "/quality.json"))
i = q["interfaces"]
assert i["watertight"] and i["materials_closed"] and i["bad_edges"] == 0, i
assert sorted(q["materials"]) == ["0", "1", "2", "3", "4"], q["materials"].keys()
for l, m in q["materials"].items():
    assert m["topology"]["watertight"] and m["topology"]["manifold"], (l, m["topology"])
PY
echo "tiny label map: ok ($SAMPLER)"
