#!/usr/bin/env bash
# baseline: marching cubes and CGAL Mesh_3 on a sphere distance field (radius
# 0.6, 20^3 voxels of 0.1) give closed genus-0 meshes on the surface; the size
# search lands near the requested vertex count; bad input fails cleanly.
set -euo pipefail
BIN=$1
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
python3 - "$T/sphere.nrrd" <<'PY'
import sys
n, h, r = 20, 0.1, 0.6
c = h * (n - 1) / 2
vals = [((i * h - c) ** 2 + (j * h - c) ** 2 + (k * h - c) ** 2) ** 0.5 - r
        for k in range(n) for j in range(n) for i in range(n)]
with open(sys.argv[1], "w") as f:
    f.write(f"NRRD0004\ntype: float\ndimension: 3\nsizes: {n} {n} {n}\nspacings: {h} {h} {h}\nencoding: ascii\n\n")
    f.write("\n".join(f"{v:.7g}" for v in vals) + "\n")
PY
# Distances to the B-spline reconstruction: trilinear interpolation and B-spline
# smoothing of a sphere's distance each move the surface by O(h^2/r) ~ 0.01.
Q="watertight,manifold,no_self_intersections,genus=0,components=1,dist_vertex_max<=0.02"
"$BIN/baseline" mc -i "$T/sphere.nrrd" --iso 0 -o "$T/mc.ply" -q
"$BIN/meshstats" "$T/mc.ply" -i "$T/sphere.nrrd" --iso 0 --require "$Q" -q
"$BIN/baseline" cgal -i "$T/sphere.nrrd" --iso 0 --size 0.12 -o "$T/cgal.off" -q --threads 1
"$BIN/meshstats" "$T/cgal.off" -i "$T/sphere.nrrd" --iso 0 --require "$Q,rr_min>=0.2" -q
"$BIN/baseline" cgal -i "$T/sphere.nrrd" --iso 0 --vertices 400 -o "$T/cgal2.ply" --stats "$T/c.json" -q --threads 1
python3 - "$T/c.json" <<'PY'
import json, sys
n = json.load(open(sys.argv[1]))["counts"]["vertices"]
assert abs(n / 400 - 1) <= 0.1, f"size search gave {n} vertices for a target of 400"
PY
# Volume meshes (--tets): CGAL Mesh_3 with cell criteria, perturbation and
# exudation. Judged by meshio: every tetrahedron positive, material 1, and the
# volume of the ball within the facet distance: |dV| <= area * distance =
# 4 pi 0.6^2 * 0.01 (5% of 4/3 pi 0.6^3).
"$BIN/baseline" cgal -i "$T/sphere.nrrd" --iso 0 --size 0.12 --distance 0.01 --tets "$T/ball.vtu" -q --threads 1 \
  --stats "$T/v.json"
"$BIN/meshstats" "$T/ball.vtu" --require "positive,boundary_manifold" -q
# A label map whose background is 1 (as in Cleaver's mickey) and a ball of label 2:
# the background is found at the corners and not meshed.
python3 - "$T/labels.nrrd" <<'PY'
import sys
n, h, r = 20, 0.1, 0.6
c = h * (n - 1) / 2
vals = [2 if ((i * h - c) ** 2 + (j * h - c) ** 2 + (k * h - c) ** 2) ** 0.5 < r else 1
        for k in range(n) for j in range(n) for i in range(n)]
with open(sys.argv[1], "w") as f:
    f.write(f"NRRD0004\ntype: uchar\ndimension: 3\nsizes: {n} {n} {n}\nspacings: {h} {h} {h}\nencoding: ascii\n\n")
    f.write(" ".join(map(str, vals)) + "\n")
PY
"$BIN/baseline" cgal-labels -i "$T/labels.nrrd" --size 0.15 --tets "$T/labels.mesh" -q --threads 1
/usr/bin/python3 - "$T/ball.vtu" "$T/v.json" "$T/labels.mesh" <<'PY'
import json, math, sys
import meshio
import numpy as np
def tets(m):
    return np.concatenate([c.data for c in m.cells if c.type == "tetra"])
def volumes(p, t):
    a, b, c, d = (p[t[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6
m = meshio.read(sys.argv[1])
t = tets(m)
v = volumes(m.points, t)
assert (v > 0).all(), v.min()
exact = 4 / 3 * math.pi * 0.6 ** 3
assert abs(v.sum() - exact) <= 4 * math.pi * 0.36 * 0.01, (v.sum(), exact)
assert (np.concatenate(m.cell_data["material"]) == 1).all()
st = json.load(open(sys.argv[2]))
names = [s["name"] for s in st["steps"]]
assert names == ["refine", "perturb", "exude"], names
q = [s["quality"]["overall"] for s in st["steps"]]
# Perturbation and exudation only take changes that improve the worst tetrahedra around them.
assert q[2]["dihedral_min"] >= q[0]["dihedral_min"] - 1e-9, q
assert st["counts"]["tet_vertices"] == len(m.points) and st["counts"]["tetrahedra"] == len(t)
lm = meshio.read(sys.argv[3])
mat = np.concatenate([d for c, d in zip(lm.cells, lm.cell_data["medit:ref"]) if c.type == "tetra"])
assert set(mat.tolist()) == {2}, set(mat.tolist())  # the background (label 1) is not meshed
lv = volumes(lm.points, tets(lm))
assert (lv > 0).all() and abs(lv.sum() - exact) < 0.15 * exact, (lv.sum(), exact)
PY
# Bad input: exit 1 or 2 with a message, no output left behind.
expect() {  # expect CODE REGEX cmd...
  local code=$1 re=$2; shift 2
  set +e; msg=$("$@" 2>&1); rc=$?; set -e
  [ $rc -eq "$code" ] || { echo "expected exit $code, got $rc: $*: $msg"; exit 1; }
  echo "$msg" | grep -Eq "$re" || { echo "unexpected message for $*: $msg"; exit 1; }
}
expect 2 "baseline: usage error: cgal: give exactly one of --vertices N or --size S" \
  "$BIN/baseline" cgal -i "$T/sphere.nrrd" -o "$T/x.ply"
expect 2 "baseline: usage error: mc: --vertices and --size are for the cgal modes" \
  "$BIN/baseline" mc -i "$T/sphere.nrrd" --size 1 -o "$T/x.ply"
expect 1 "baseline: error: .*isovalue 5 is outside the value range" \
  "$BIN/baseline" mc -i "$T/sphere.nrrd" --iso 5 -o "$T/x.ply"
expect 1 "baseline: error: CGAL Mesh_3 labels baseline: voxel type float; expected an integer label map" \
  "$BIN/baseline" cgal-labels -i "$T/sphere.nrrd" --size 0.2 -o "$T/x.ply"
expect 2 "baseline: usage error: --output .*x.xyz.*unknown mesh extension" \
  "$BIN/baseline" mc -i "$T/sphere.nrrd" -o "$T/x.xyz"
expect 2 "baseline: usage error: --tets .*x.obj.*unknown tetrahedral mesh extension" \
  "$BIN/baseline" cgal -i "$T/sphere.nrrd" --size 0.12 --tets "$T/x.obj"
expect 2 "baseline: usage error: mc: --tets is for the cgal modes" \
  "$BIN/baseline" mc -i "$T/sphere.nrrd" --tets "$T/x.mesh"
expect 2 "baseline: usage error: give -o SURFACE, --tets VOLUME, or both" \
  "$BIN/baseline" cgal -i "$T/sphere.nrrd" --size 0.12
expect 2 "baseline: usage error: CGAL Mesh_3 baseline: cell radius-edge ratio must be >= 2" \
  "$BIN/baseline" cgal -i "$T/sphere.nrrd" --size 0.12 --radius-edge 1.5 --tets "$T/x.mesh"
expect 2 "baseline: usage error: --outside \"ground\": expected a non-negative integer label or auto" \
  "$BIN/baseline" cgal-labels -i "$T/labels.nrrd" --size 0.15 --outside ground --tets "$T/x.mesh"
[ ! -e "$T/x.ply" ] || { echo "a failed run left $T/x.ply"; exit 1; }
[ ! -e "$T/x.mesh" ] || { echo "a failed run left $T/x.mesh"; exit 1; }
echo "baseline: ok"
