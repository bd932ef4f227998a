#!/usr/bin/env bash
# Issue 19: `make tets` (one material) and `make materials-tets` (several) end in
# conforming tetrahedra. Checked by meshio (the Debian interpreter's) against
# the surface files the same run wrote: the volume mesh's boundary faces are
# exactly the surface's triangles (same coordinates), the tetrahedra fill the
# surface's enclosed volume (divergence theorem, to rounding), every
# tetrahedron is positive, and the issue's quality bounds hold.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
/usr/bin/python3 - "$T" <<'PY'
import sys
import numpy as np
T = sys.argv[1]
def nrrd(path, v, spacing):
    with open(path, "wb") as o:
        o.write(f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: {v.shape[2]} {v.shape[1]} {v.shape[0]}\n"
                f"spacings: {spacing} {spacing} {spacing}\nencoding: raw\n\n".encode() + np.ascontiguousarray(v).tobytes())
z, y, x = np.mgrid[0:28, 0:28, 0:28] - 13.5
r = np.sqrt(x * x + y * y + z * z)
nrrd(f"{T}/ball.nrrd", (r < 10).astype(np.uint8), 1)
nrrd(f"{T}/nested.nrrd", np.where(r < 5.5, 2, np.where(r < 11, 1, 0)).astype(np.uint8), 1)
# A grey-level ball, material above the isovalue (as in CT): 200 exp(-(r/9)^2) = 100 at r = 9 sqrt(ln 2).
nrrd(f"{T}/grey.nrrd", np.round(200 * np.exp(-(r / 9) ** 2)).astype(np.uint8), 1)
PY
# Grey level: the packing must fill the material side (F > ISO), not the outside.
make -s -f "$SRC/Makefile.pipeline" tets INPUT="$T/grey.nrrd" ISO=100 OUT="$T/grey" BIN="$BIN" TETS=mesh \
  REQUIRE_TETS="positive,boundary_manifold" 2> "$T/grey.err" || { cat "$T/grey.err" >&2; exit 1; }
/usr/bin/python3 - "$T/grey" <<'PY'
import json, sys
import numpy as np
import meshio
d = sys.argv[1]
ip = meshio.read(f"{d}/interior.ply").points
r = np.linalg.norm(ip - 13.5, axis=1)
R = 9 * np.sqrt(np.log(2))  # the isosurface, to voxel rounding of the values
assert len(ip) > 10 and (r < R + 0.5).all(), (len(ip), r.max(), R)
c = json.load(open(f"{d}/work/tets.json"))["counts"]
assert c["interior_outside"] == 0 and c["interior_kept"] > 0.9 * len(ip), c
PY
make -s -f "$SRC/Makefile.pipeline" tets INPUT="$T/ball.nrrd" OUT="$T/ball" BIN="$BIN" TETS=vtu \
  REQUIRE_TETS="positive,boundary_manifold,dihedral_min>=12,dihedral_max<=160,share_25_140>=0.99,rr_mean>=0.8" \
  2> "$T/ball.err" || { cat "$T/ball.err" >&2; exit 1; }
tail -n 1 "$T/ball.err" | grep -Eq '^tets: [0-9]+ vertices, [0-9]+ tetrahedra in 1 material' ||
  { echo "bad summary line" >&2; cat "$T/ball.err" >&2; exit 1; }
for f in surface.ply interior.ply volume.vtu volume_quality.json volume.png work/h_volume.nrrd work/tets.json; do
  test -s "$T/ball/$f" || { echo "missing $f" >&2; ls -R "$T/ball" >&2; exit 1; }
done
SAMPLER=multiparticles
[ -x "$BIN/multiparticles" ] || SAMPLER=stand-in
make -s -f "$SRC/Makefile.pipeline" materials-tets INPUT="$T/nested.nrrd" OUT="$T/nested" BIN="$BIN" R=1 \
  SAMPLER=$SAMPLER REQUIRE_TETS="positive,boundary_manifold,triangles_match" 2> "$T/nested.err" ||
  { cat "$T/nested.err" >&2; exit 1; }
/usr/bin/python3 - "$T" <<'PY'
import json, sys
import numpy as np
import meshio
T = sys.argv[1]

def tet_volumes(p, t):
    a, b, c, d = (p[t[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6

def boundary_faces(t, mat):
    # faces of the tetrahedra with their material; a face seen once is on the
    # outer boundary, a face between two materials is an interface
    faces = {}
    for k, tet in enumerate(t):
        for f in ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1)):
            key = tuple(sorted(tet[list(f)]))
            faces.setdefault(key, []).append(mat[k])
    return {k for k, v in faces.items() if len(v) == 1 or v[0] != v[1]}

def check(vol_path, surf_path, nmat):
    m = meshio.read(vol_path)
    p = m.points
    t = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
    key = "material" if "material" in m.cell_data else "medit:ref"
    mat = np.concatenate([d for c, d in zip(m.cells, m.cell_data[key]) if c.type == "tetra"])
    v = tet_volumes(p, t)
    assert (v > 0).all(), f"{vol_path}: {(v <= 0).sum()} tetrahedra not positive"
    assert len(set(mat.tolist())) == nmat, f"{vol_path}: materials {sorted(set(mat.tolist()))}"
    s = meshio.read(surf_path)
    tri = np.concatenate([c.data for c in s.cells if c.type == "triangle"])
    # The surface's vertices are the volume mesh's first ones, coordinates equal.
    n = len(s.points)
    assert np.array_equal(np.asarray(p[:n], np.float32), np.asarray(s.points, np.float32)), "boundary vertices moved"
    got = boundary_faces(t, mat)
    want = {tuple(sorted(f)) for f in tri}
    assert got == want, f"{vol_path}: {len(want - got)} surface triangles missing, {len(got - want)} extra faces"
    if nmat == 1:
        a, b, c = (s.points[tri[:, k]].astype(np.float64) for k in range(3))
        enclosed = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6
        assert abs(v.sum() - abs(enclosed)) <= 1e-9 * abs(enclosed), (v.sum(), enclosed)
    # Interior points: the packing's points are in the mesh too (TetGen keeps them).
    return len(t)

check(f"{T}/ball/volume.vtu", f"{T}/ball/surface.ply", 1)
n_mesh = check(f"{T}/nested/volume.mesh", f"{T}/nested/interfaces.ply", 2)
# The default TETS writes MEDIT and VTK XML from one run: the same tetrahedra in both.
assert check(f"{T}/nested/volume.vtu", f"{T}/nested/interfaces.ply", 2) == n_mesh
q = json.load(open(f"{T}/ball/volume_quality.json"))
o = q["overall"]
assert o["dihedral_min"] >= 12 and o["dihedral_max"] <= 160 and o["rr_mean"] >= 0.8, o
ip = meshio.read(f"{T}/ball/interior.ply")
r = np.linalg.norm(ip.points - 13.5, axis=1)
assert len(ip.points) > 100 and (r < 10.5).all(), (len(ip.points), r.max())
PY
