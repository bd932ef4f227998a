#!/usr/bin/env bash
# tetlabel --conform (issue 19): conforming tetrahedra of a kept surface plus
# interior points. One material (an icosphere in the implicit unit sphere)
# and two (tetlabel's own interfaces of a split ball), written in every
# tetrahedral format and read back by Debian's meshio; the boundary must be
# the surface's vertices and triangles, the volume the polyhedron's, the
# counts those of --stats. Bad input: an open surface, an interface mesh
# without labels, a missing file (exit 1); an unknown extension, -o with
# --conform (exit 2, before any input is read); nothing half-written.
set -euo pipefail
BIN=$1; SRC=$2
PY=/usr/bin/python3
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
$PY -c "import meshio" 2>/dev/null || { echo "tets_test: python3-meshio missing (scripts/setup installs it)" >&2; exit 1; }
TL="$BIN/tetlabel"; MC="$BIN/mcinit"

# --- fixtures ------------------------------------------------------------------
# sphere.ply: icosphere (2 subdivisions: 162 vertices, 320 triangles) of radius
# 0.999, ASCII doubles; open.ply: the same minus one triangle; inner.ply: a
# body-centred cubic lattice of spacing 0.25 at least 0.18 inside it; ball.nrrd:
# a ball of radius 6 split at x = 9.5 into labels 1 | 2, background 0.
$PY - "$T" <<'PYEOF'
import math, struct, sys
T = sys.argv[1]
t = (1 + 5 ** 0.5) / 2
V = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
     (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
F = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
     (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
     (8, 6, 7), (9, 8, 1)]
for _ in range(2):
    mid = {}
    def m(a, b):
        k = (min(a, b), max(a, b))
        if k not in mid:
            V.append(tuple((V[a][i] + V[b][i]) / 2 for i in range(3))); mid[k] = len(V) - 1
        return mid[k]
    G = []
    for a, b, c in F:
        x, y, z = m(a, b), m(b, c), m(c, a)
        G += [(a, x, z), (b, y, x), (c, z, y), (x, y, z)]
    F = G
V = [tuple(0.999 * c / math.sqrt(sum(q * q for q in v)) for c in v) for v in V]
def ply(name, verts, faces):
    with open(f"{T}/{name}", "w") as o:
        o.write(f"ply\nformat ascii 1.0\nelement vertex {len(verts)}\nproperty double x\nproperty double y\n"
                f"property double z\nelement face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
        o.writelines("%.17g %.17g %.17g\n" % v for v in verts)
        o.writelines("3 %d %d %d\n" % f for f in faces)
ply("sphere.ply", V, F)
ply("open.ply", V, F[1:])
h = 0.25; n = 5; P = []
for i in range(-n, n + 1):
    for j in range(-n, n + 1):
        for k in range(-n, n + 1):
            for o in (0, 0.5):
                p = ((i + o) * h, (j + o) * h, (k + o) * h)
                if math.sqrt(sum(c * c for c in p)) < 0.999 - 0.18: P.append(p)
ply("inner.ply", P, [])
open(f"{T}/counts", "w").write(f"{len(V)} {len(F)} {len(P)}\n")
n = 20; c = (n - 1) / 2; data = bytearray()
for k in range(n):
    for j in range(n):
        for i in range(n):
            data += struct.pack("B", 0 if math.dist((i, j, k), (c, c, c)) > 6 else (1 if i < 10 else 2))
open(f"{T}/ball.nrrd", "wb").write(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 20 20 20\n"
                                   b"space: left-posterior-superior\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n"
                                   b"space origin: (10,20,30)\nendian: little\nencoding: raw\n\n" + bytes(data))
# Lattice for the ball (world = index + origin), spacing 1.5.
Q = []
for i in range(-6, 7):
    for j in range(-6, 7):
        for k in range(-6, 7):
            for o in (0, 0.75):
                p = (i * 1.5 + o, j * 1.5 + o, k * 1.5 + o)
                if math.sqrt(sum(q * q for q in p)) < 5: Q.append((p[0] + 10 + c, p[1] + 20 + c, p[2] + 30 + c))
ply("ball_inner.ply", Q, [])
PYEOF
read NV NF NP < "$T/counts"

expect_fail() {  # expect_fail CODE REGEX cmd...: exit CODE and REGEX on stderr
  local code=$1 re=$2; shift 2
  local rc=0
  "$@" 2> "$T/err" || rc=$?
  if [ "$rc" != "$code" ]; then echo "expected exit $code, got $rc: $*" >&2; cat "$T/err" >&2; exit 1; fi
  grep -Eq "$re" "$T/err" || { echo "expected /$re/ in stderr of: $*" >&2; cat "$T/err" >&2; exit 1; }
}

# --- one material, every format ---------------------------------------------------
for ext in mesh vtu vtk msh; do
  "$TL" "$T/inner.ply" --conform "$T/sphere.ply" --implicit sphere --tets "$T/ball.$ext" \
    --min-dihedral 12 --stats "$T/ball_$ext.json" -q
done
# Requirements: met (exit 0) and not met (exit 3, mesh still written).
"$TL" "$T/inner.ply" --conform "$T/sphere.ply" --implicit sphere --tets "$T/req.mesh" -q \
  --require "positive,triangles_match,boundary_manifold,max_dihedral<=170"
expect_fail 3 "tetlabel: check failed: .*req2.mesh.*min_dihedral>=65" \
  "$TL" "$T/inner.ply" --conform "$T/sphere.ply" --implicit sphere --tets "$T/req2.mesh" -q --require "min_dihedral>=65"
test -s "$T/req2.mesh"

# --- two materials: tetlabel's interfaces of the split ball ----------------------------
"$MC" "$T/ball.nrrd" "$T/seeds.ply" --junctions -q
"$TL" "$T/seeds.ply" --materials "$T/ball.nrrd" -o "$T/if.ply" -q
"$TL" "$T/ball_inner.ply" --conform "$T/if.ply" --materials "$T/ball.nrrd" --tets "$T/split.vtu" \
  --stats "$T/split.json" -q

$PY - "$T" "$NV" "$NF" "$NP" <<'PYEOF'
import json, sys, warnings
import numpy as np
import meshio
warnings.simplefilter("ignore")
T, NV, NF, NP = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
S = meshio.read(f"{T}/sphere.ply")
SP, SF = S.points, np.concatenate([b.data for b in S.cells if b.type == "triangle"])
assert SP.shape == (NV, 3) and SF.shape == (NF, 3)
exact = sum(np.dot(SP[a], np.cross(SP[b], SP[c])) for a, b, c in SF) / 6  # the polyhedron's volume

def cells(m, kind):
    return np.concatenate([b.data for b in m.cells if b.type == kind]) if any(b.type == kind for b in m.cells) else np.zeros((0, 3 if kind == "triangle" else 4), int)

def volumes(P, C):
    a, b, c, d = (P[C[:, i]] for i in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6

def boundary_faces(C):
    faces = {}
    for t in C:
        for f in ((t[1], t[2], t[3]), (t[0], t[2], t[3]), (t[0], t[1], t[3]), (t[0], t[1], t[2])):
            k = tuple(sorted(f)); faces[k] = faces.get(k, 0) + 1
    return {k for k, n in faces.items() if n == 1}

for ext in ("mesh", "vtu", "vtk", "msh"):
    st = json.load(open(f"{T}/ball_{ext}.json"))
    cn = st["counts"]; q = st["quality"]
    m = meshio.read(f"{T}/ball.{ext}")
    C = cells(m, "tetra")
    assert C.shape[0] == cn["tetrahedra"] > 0, (ext, C.shape, cn)
    assert m.points.shape[0] == cn["vertices"], (ext, m.points.shape, cn)
    assert cn["interior_kept"] == NP and cn["interior_given"] == NP, (ext, cn)
    assert cn["vertices"] == NV + NP + cn["steiner_points"], cn
    # The boundary: the surface's vertices first (exactly: files store doubles or %.17g), its triangles.
    assert np.abs(m.points[:NV] - SP).max() < 1e-12, (ext, np.abs(m.points[:NV] - SP).max())
    assert boundary_faces(C) == {tuple(sorted(f)) for f in SF}, ext
    vol = volumes(m.points, C)
    assert (vol > 0).all(), (ext, vol.min())
    assert abs(vol.sum() - exact) < 1e-9 * exact, (ext, vol.sum(), exact)
    assert [s["name"] for s in st["steps"]] == ["cdt", "refine", "optimise", "smooth"], st["steps"]
    # ODT smoothing keeps the boundary and cannot lower the smallest radius ratio.
    assert st["steps"][3]["quality"]["overall"]["rr_min"] >= st["steps"][2]["quality"]["overall"]["rr_min"], st["steps"]
    assert q["triangles_match"] and q["positive"], q
    if ext == "vtu":
        assert (np.concatenate(m.cell_data["material"]) == 1).all()
    if ext == "mesh":
        T3 = cells(m, "triangle")
        assert {tuple(sorted(f)) for f in T3} == {tuple(sorted(f)) for f in SF}, "medit triangles"

# Two materials: both kept, the interfaces of if.ply inside, each region one material.
st = json.load(open(f"{T}/split.json"))
I = meshio.read(f"{T}/if.ply")
IF = cells(I, "triangle")
la = np.concatenate(I.cell_data["label_a"]); lb = np.concatenate(I.cell_data["label_b"])
m = meshio.read(f"{T}/split.vtu")
C = cells(m, "tetra"); mat = np.concatenate(m.cell_data["material"]).reshape(-1)
assert C.shape[0] == st["counts"]["tetrahedra"], (C.shape, st["counts"])
assert sorted(set(mat.tolist())) == [1, 2], set(mat.tolist())
assert st["counts"]["regions"] == 2 and st["counts"]["dropped_regions"] == 0, st["counts"]
assert np.abs(m.points[:I.points.shape[0]] - I.points).max() == 0
assert (volumes(m.points, C) > 0).all()
faces = {}
for t, l in zip(C, mat):
    for f in ((t[1], t[2], t[3]), (t[0], t[2], t[3]), (t[0], t[1], t[3]), (t[0], t[1], t[2])):
        faces.setdefault(tuple(sorted(f)), []).append(int(l))
changes = {k: tuple(sorted(v + [0] * (2 - len(v)))) for k, v in faces.items() if len(v) == 1 or v[0] != v[1]}
want = {tuple(sorted(f)): (int(a), int(b)) for f, a, b in zip(IF, la, lb)}
assert changes == want, (len(changes), len(want))
print("tets_test: ok", {e: json.load(open(f"{T}/ball_{e}.json"))["counts"]["tetrahedra"] for e in ("mesh", "vtu", "vtk", "msh")})
PYEOF

# --- bad input ---------------------------------------------------------------------
expect_fail 1 "tetlabel: error: .*open.ply.*not a closed surface: 3 edges in one triangle only" \
  "$TL" "$T/inner.ply" --conform "$T/open.ply" --implicit sphere --tets "$T/bad1.vtu"
expect_fail 1 "tetlabel: error: .*sphere.ply.*no face properties label_a and label_b" \
  "$TL" "$T/inner.ply" --conform "$T/sphere.ply" --materials "$T/ball.nrrd" --tets "$T/bad2.vtu"
expect_fail 1 "tetlabel: error: .*nope.ply.*no such file" \
  "$TL" "$T/nope.ply" --conform "$T/sphere.ply" --implicit sphere --tets "$T/bad3.vtu"
# Usage errors come before any input is read (the inputs here do not exist).
expect_fail 2 "tetlabel: usage error: --tets .*v.obj.*unknown tetrahedral mesh extension" \
  "$TL" "$T/nope.ply" --conform "$T/nope2.ply" --implicit sphere --tets "$T/v.obj"
expect_fail 2 "tetlabel: usage error: --conform writes only --tets: drop -o" \
  "$TL" "$T/nope.ply" --conform "$T/nope2.ply" --implicit sphere --tets "$T/v.vtu" -o "$T/s.ply"
expect_fail 2 "tetlabel: usage error: --conform needs --tets" \
  "$TL" "$T/nope.ply" --conform "$T/nope2.ply" --implicit sphere
expect_fail 2 "tetlabel: usage error: requirement \"frob\" is unknown" \
  "$TL" "$T/nope.ply" --conform "$T/nope2.ply" --implicit sphere --tets "$T/v.vtu" --require frob
expect_fail 2 "tetlabel: usage error: --min-dihedral needs --conform" \
  "$TL" "$T/inner.ply" --implicit sphere -o "$T/s.ply" --min-dihedral 10
expect_fail 2 "tetlabel: usage error: --boundary-clearance needs --conform" \
  "$TL" "$T/inner.ply" --implicit sphere -o "$T/s.ply" --boundary-clearance 0.1
expect_fail 2 "boundary-clearance: Value 1.5 not in range" \
  "$TL" "$T/nope.ply" --conform "$T/nope2.ply" --implicit sphere --tets "$T/v.vtu" --boundary-clearance 1.5
# Nothing half-written: no output and no temporary file from the failed runs.
leftover=$(ls "$T" | grep -E '^(bad[0-9]|v\.|s\.ply)|\.tmp' || true)
[ -z "$leftover" ] || { echo "tets_test: left behind: $leftover" >&2; exit 1; }
echo "tets_test: all passed"
