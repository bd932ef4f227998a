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
[ ! -e "$T/x.ply" ] || { echo "a failed run left $T/x.ply"; exit 1; }
echo "baseline: ok"
