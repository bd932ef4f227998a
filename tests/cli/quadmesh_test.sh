#!/usr/bin/env bash
# Quad packing end to end (issue #20): particles --quads on a sphere writes two
# balanced types; tetlabel meshes them; quadmesh pairs the triangles into quads
# and writes .ply .obj .off with the quads kept, which meshio (an independent
# reader; OFF parsed here, meshio reads triangles only) opens with the same
# quad and triangle counts as our --stats; the
# mesh is closed (every edge in two faces) with Euler characteristic 2.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
PY=/usr/bin/python3
"$BIN/particles" --implicit sphere:r=1 --spacing 0.12 --quads -o "$T/typed.ply" -q --stats "$T/p.json"
# The one-grain colouring is sequential and the sweeps are coloured: the same bits for any --threads.
"$BIN/particles" --implicit sphere:r=1 --spacing 0.12 --quads -o "$T/typed1.ply" -q --threads 1
cmp "$T/typed.ply" "$T/typed1.ply"
"$BIN/tetlabel" "$T/typed.ply" --implicit sphere:r=1 --iso 0 -o "$T/tri.ply" -q
for ext in ply obj off; do
  "$BIN/quadmesh" "$T/tri.ply" --types "$T/typed.ply" -o "$T/quads.$ext" -q --stats "$T/q_$ext.json"
done
# Smoothed on the sphere: the same faces, corners closer to 90 (the stats keep the unsmoothed figures).
"$BIN/quadmesh" "$T/tri.ply" --types "$T/typed.ply" -o "$T/smooth.ply" --implicit sphere:r=1 --iso 0 -q \
  --stats "$T/q_smooth.json"
# The baseline: Gmsh's Blossom recombination of the same triangles, vertices kept.
"$BIN/quadmesh" "$T/tri.ply" --gmsh -o "$T/gmsh.ply" -q --stats "$T/q_gmsh.json"
# The surface has no type of its own: without --types it is refused, naming the file.
if "$BIN/quadmesh" "$T/tri.ply" -o "$T/x.ply" -q 2> "$T/err"; then echo "no-type surface accepted"; exit 1; fi
grep -q "tri.ply.*no vertex property .type." "$T/err"
test ! -e "$T/x.ply"
# meshstats reads the polygon meshes back with their quads (and measures their fan triangulation against the
# sphere); its quad figures must equal quadmesh's own.
for ext in ply obj off; do
  "$BIN/meshstats" "$T/quads.$ext" --implicit sphere:r=1 --iso 0 -o "$T/ms_$ext.json" -q --require "watertight,quad_share>=0.5"
done
rc=0; "$BIN/meshstats" "$T/quads.ply" -q --require "quad_share>=0.999" 2> "$T/err" || rc=$?
[ "$rc" = 3 ] || { echo "quad_share>=0.999 should fail with exit 3, got $rc"; cat "$T/err"; exit 1; }
rc=0; "$BIN/meshstats" "$T/tri.ply" -q --require "quad_share>=0.5" 2> "$T/err" || rc=$?
[ "$rc" = 2 ] || { echo "quad_share on a triangle mesh should be a usage error, got $rc"; exit 1; }
grep -q "needs a polygon mesh with quads" "$T/err"
$PY - "$T" <<'PY'
import json, sys
import numpy as np
T = sys.argv[1]
try:
    import meshio
except ImportError:
    sys.exit(77)
# particles --quads: two types, about half each (the initial mix is 50/50, splits alternate).
m = meshio.read(f"{T}/typed.ply")
t = np.asarray(m.point_data["type"])
assert set(np.unique(t)) <= {0.0, 1.0}, np.unique(t)
share = t.mean()
assert 0.35 < share < 0.65, share
q = json.load(open(f"{T}/q_ply.json"))["quality"]
assert q["watertight"], q
assert q["quads"] > 0.7 * q["faces"], q  # a sphere packing: most faces are quads
def read_off(path):  # meshio's OFF reader takes triangles only: the format is simple enough to parse here
    tok = open(path).read().split()
    assert tok[0] == "OFF"
    nv, nf = int(tok[1]), int(tok[2])
    pts = np.array(tok[4:4 + 3 * nv], float).reshape(nv, 3)
    faces, i = [], 4 + 3 * nv
    for _ in range(nf):
        n = int(tok[i]); faces.append([int(x) for x in tok[i + 1:i + 1 + n]]); i += 1 + n
    assert i == len(tok)
    return pts, faces
for ext in ("ply", "obj", "off"):
    if ext == "off":
        points, faces = read_off(f"{T}/quads.off")
    else:
        mesh = meshio.read(f"{T}/quads.{ext}")
        points, faces = mesh.points, [f for c in mesh.cells for f in c.data.tolist()]
    cells = {3: 0, 4: 0}
    for f in faces:
        cells[len(f)] += 1
    assert cells[4] == q["quads"], (ext, cells, q["quads"])
    assert cells[3] == q["triangles"], (ext, cells, q["triangles"])
    edges = {}
    for f in faces:
        for i in range(len(f)):
            e = tuple(sorted((f[i], f[(i + 1) % len(f)])))
            edges[e] = edges.get(e, 0) + 1
    assert all(n == 2 for n in edges.values()), ext
    used = len({v for f in faces for v in f})
    assert used - len(edges) + len(faces) == 2, (ext, used, len(edges), len(faces))
    # Points on the unit sphere, in double precision from our writer (|r| - 1 is the packing's own 1e-6).
    r = np.linalg.norm(points, axis=1)
    assert np.abs(r - 1).max() < 1e-4, (ext, np.abs(r - 1).max())
for ext in ("ply", "obj", "off"):
    ms = json.load(open(f"{T}/ms_{ext}.json"))
    pq = ms["polygons"]
    for k in ("quads", "triangles", "corner_share_70_110", "valence4_share", "corner_min", "corner_max"):
        assert abs(pq[k] - q[k]) <= 1e-9 * max(1.0, abs(q[k])), (ext, k, pq[k], q[k])
    assert ms["topology"]["boundary_edges"] == 0, ext
    # Vertices on the unit sphere: the fan triangles' centroids lie inside it by at most the sagitta of a
    # quad's diagonal (spacing 0.12, diagonal ~0.17 -> (0.17/2)^2 / 2 = 0.0036).
    assert ms["distance_to_surface"]["centroid_max"] < 0.01, (ext, ms["distance_to_surface"])
    assert ms["distance_to_surface"]["vertex_max"] < 1e-4, (ext, ms["distance_to_surface"])
# Smoothing: the faces of the unsmoothed mesh, every vertex still on the sphere (our PLY writes doubles;
# projection tolerance 1e-6 of the mean edge), and a corner share that did not drop.
raw, smooth = meshio.read(f"{T}/quads.ply"), meshio.read(f"{T}/smooth.ply")
assert [c.data.tolist() for c in raw.cells] == [c.data.tolist() for c in smooth.cells]
r = np.linalg.norm(smooth.points, axis=1)
assert np.abs(r - 1).max() < 1e-6, np.abs(r - 1).max()
qs = json.load(open(f"{T}/q_smooth.json"))
assert qs["quality_unsmoothed"]["corner_share_70_110"] == q["corner_share_70_110"], qs["quality_unsmoothed"]
assert qs["quality"]["corner_share_70_110"] >= q["corner_share_70_110"], (qs["quality"], q)
assert qs["smoothing"]["corner_objective_after"] < qs["smoothing"]["corner_objective_before"], qs["smoothing"]
# Gmsh: the input's vertices, each triangle used once (2 per quad), closed.
g = json.load(open(f"{T}/q_gmsh.json"))
assert g["parameters"]["method"] == "gmsh" and g["parameters"]["recombination_algorithm"] == 1, g["parameters"]
assert g["counts"]["vertices_out"] == g["counts"]["vertices_in"], g["counts"]
gq = g["quality"]
assert 2 * gq["quads"] + gq["triangles"] == g["counts"]["triangles_in"], (gq, g["counts"])
assert gq["watertight"] and gq["quads"] > 0.9 * gq["faces"], gq
gm = meshio.read(f"{T}/gmsh.ply")
assert sum(len(c.data) for c in gm.cells if c.type == "quad") == gq["quads"]
print("ok")
PY
