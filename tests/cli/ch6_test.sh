#!/usr/bin/env bash
# Chapter 6 tools on tiny generated label maps: tighten --per-label, volconv
# --min-voxels/--argmax, tetlabel --materials (interfaces water-tight, material
# surfaces closed, manifold and sharing their faces), meshstats on interface
# meshes (exit 3 when a check fails), and bad input: one label, labels that
# never touch, thousands of labels, stray voxels, non-integer data.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT

# --- fixtures: raw NRRDs written by python ------------------------------------
python3 - "$T" <<'PY'
import struct, sys, math
T = sys.argv[1]
def write(name, n, f, typ="uint8"):
    fmt = {"uint8": "B", "uint16": "H", "float": "f"}[typ]
    data = bytearray()
    for k in range(n):
        for j in range(n):
            for i in range(n):
                data += struct.pack("<" + fmt, f(i, j, k))
    with open(f"{T}/{name}", "wb") as o:
        o.write(f"NRRD0004\ntype: {typ}\ndimension: 3\nsizes: {n} {n} {n}\nspacings: 1 1 1\n"
                f"endian: little\nencoding: raw\n\n".encode() + bytes(data))
def split_ball(i, j, k, n=20):  # ball of radius 6 split at x = 9.5 into 1 | 2, background 0
    c = (n - 1) / 2
    if math.dist((i, j, k), (c, c, c)) > 6: return 0
    return 1 if i < 10 else 2
write("tiny.nrrd", 20, split_ball)
write("one.nrrd", 8, lambda i, j, k: 3)
write("apart.nrrd", 20, lambda i, j, k: 1 if math.dist((i, j, k), (5, 9, 9)) <= 3 else (2 if math.dist((i, j, k), (14, 9, 9)) <= 3 else 0))
write("many.nrrd", 16, lambda i, j, k: i + 16 * j + 256 * k, "uint16")
write("stray.nrrd", 20, lambda i, j, k: 9 if (i, j, k) in ((2, 2, 2), (17, 3, 15)) else split_ball(i, j, k))
write("frac.nrrd", 8, lambda i, j, k: 0.5 if (i, j, k) == (3, 4, 5) else float(i > 3), "float")
PY

VC="$BIN/volconv"; TI="$BIN/tighten"; MC="$BIN/mcinit"; TL="$BIN/tetlabel"; MS="$BIN/meshstats"
expect_fail() {  # expect_fail REGEX cmd...: non-zero exit and REGEX on stderr
  local re=$1; shift
  if "$@" 2> "$T/err"; then echo "expected failure: $*" >&2; exit 1; fi
  grep -Eq "$re" "$T/err" || { echo "message does not match /$re/:" >&2; cat "$T/err" >&2; exit 1; }
}

# 1. Per-label tightening: one signed distance per label on one grid.
"$TI" "$T/tiny.nrrd" "$T/sdf_%d.nrrd" --per-label --radius 1 -q --stats "$T/ti.json"
for l in 0 1 2; do "$VC" --info "$T/sdf_$l.nrrd" > "$T/i$l.json"; done
python3 - "$T" <<'PY'
import json, sys
T = sys.argv[1]
st = json.load(open(f"{T}/ti.json"))
assert st["counts"]["labels"] == 3, st["counts"]
infos = [json.load(open(f"{T}/i{l}.json")) for l in (0, 1, 2)]
for i in infos:
    assert i["dims"] == [20, 20, 20] and i["type"] == "float", i
    assert i["min"] < -2 and i["max"] > 2, i   # each label has inside and outside
PY

# 2. tetlabel --materials on junction seeds of the label map: interfaces
#    water-tight, every material closed and manifold, faces shared.
"$MC" "$T/tiny.nrrd" "$T/seeds.ply" --junctions -q
SPEC="0=$T/sdf_0.nrrd,1=$T/sdf_1.nrrd,2=$T/sdf_2.nrrd"
"$TL" "$T/seeds.ply" --materials "$T/tiny.nrrd" -o "$T/if.ply" --material-surfaces "$T" --tets "$T/v.mesh" -q --stats "$T/tl.json"
test -f "$T/material_1.ply" && test -f "$T/material_2.ply" && test ! -f "$T/material_0.ply"
grep -q "^Tetrahedra" "$T/v.mesh"
"$MS" "$T/if.ply" -o "$T/q.json" -q --require watertight,manifold,labels_consistent,no_self_intersections
python3 - "$T" <<'PY'
import json, sys
T = sys.argv[1]
st = json.load(open(f"{T}/tl.json"))["counts"]
assert st["pairs"] == [[0, 1], [0, 2], [1, 2]], st["pairs"]
assert st["boundary_edges"] == 0, st
for l in ("1", "2"):
    m = st["materials"][l]
    assert m["closed_manifold"] and m["components"] == 1, (l, m)
q = json.load(open(f"{T}/q.json"))
i = q["interfaces"]
assert i["boundary_edges"] == 0 and i["bad_edges"] == 0 and i["self_faces"] == 0, i
assert i["junction_edges"] > 10, i      # the triple circle, radius ~6 voxels
assert set(q["materials"]) == {"0", "1", "2"}, q["materials"].keys()
# shared faces: F1 + F2 = F0 + 2 F(1,2), and F0 = F(0,1) + F(0,2)
F = {l: q["materials"][l]["faces"] for l in q["materials"]}
assert (F["1"] + F["2"] - F["0"]) % 2 == 0 and F["1"] + F["2"] > F["0"], F
assert q["overall"]["faces"] == (F["0"] + F["1"] + F["2"]) // 2, (q["overall"]["faces"], F)
PY
# The same with the per-label distances as the material set, and a pattern.
"$TL" "$T/seeds.ply" --materials "$SPEC" -o "$T/if2.ply" --material-surfaces "$T/m%d.off" -q
test -f "$T/m1.off" && test -f "$T/m2.off"

# 3. meshstats: an interface mesh with a hole fails watertight (exit 3).
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nproperty int label_a\nproperty int label_b\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 1 2\n' > "$T/open_if.ply"
set +e; "$MS" "$T/open_if.ply" --require watertight,labels_consistent 2> "$T/err"; rc=$?; set -e
test $rc -eq 3 || { echo "meshstats exit $rc, expected 3" >&2; cat "$T/err" >&2; exit 1; }
grep -q "watertight (3 boundary edges)" "$T/err"

# 4. Bad input.
expect_fail "only 1 label \(3\); expected at least 2 materials" "$TL" "$T/seeds.ply" --materials "$T/one.nrrd" -o "$T/x.ply"
expect_fail "only one label \(3\); expected at least 2 materials" "$TI" "$T/one.nrrd" "$T/s_%d.nrrd" --per-label --radius 1
expect_fail "more than 256 distinct labels" "$TL" "$T/seeds.ply" --materials "$T/many.nrrd" -o "$T/x.ply"
expect_fail "voxel \(3,4,5\) is 0.5; expected a label map with integer values" "$TL" "$T/seeds.ply" --materials "$T/frac.nrrd" -o "$T/x.ply"
expect_fail "voxel \(3,4,5\) is 0.5; expected a label map" "$TI" "$T/frac.nrrd" "$T/s_%d.nrrd" --per-label --radius 1
expect_fail "expected integer labels" "$VC" "$T/frac.nrrd" "$T/x.nrrd" --min-voxels 2
expect_fail "label 1 is given twice" "$TL" "$T/seeds.ply" --materials "1=$T/sdf_1.nrrd,1=$T/sdf_2.nrrd" -o "$T/x.ply"
expect_fail "expected a pattern with one %d" "$TI" "$T/tiny.nrrd" "$T/s.nrrd" --per-label --radius 1
expect_fail "need --materials" "$TL" "$T/seeds.ply" --implicit sphere -o "$T/x.ply" --material-surfaces "$T"
# Stray single voxels: dropped by --min-voxels (they join their neighbours).
"$VC" "$T/stray.nrrd" "$T/clean.nrrd" --min-voxels 3 -q --stats "$T/vc.json"
"$VC" --info "$T/clean.nrrd" | python3 -c 'import json,sys; d=json.load(sys.stdin); assert sorted(d["labels"], key=int) == ["0","1","2"], d["labels"]'
python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); assert d["dropped_labels"] == [9], d' "$T/vc.json"
# Labels that never touch: a sensible result, two separate closed surfaces, no 1|2 interface.
"$MC" "$T/apart.nrrd" "$T/aseeds.ply" --junctions -q
"$TL" "$T/aseeds.ply" --materials "$T/apart.nrrd" -o "$T/aif.ply" -q --stats "$T/atl.json"
python3 -c 'import json,sys; c=json.load(open(sys.argv[1]))["counts"]; assert c["pairs"] == [[0,1],[0,2]] and c["boundary_edges"] == 0, c' "$T/atl.json"
# Indicator volumes (positive inside) -> argmax label map.
"$VC" "1=+$T/sdf_1.nrrd,2=$T/sdf_2.nrrd" "$T/am.nrrd" --argmax -q
echo "ch6 CLI checks passed"
