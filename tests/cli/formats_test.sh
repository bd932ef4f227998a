#!/usr/bin/env bash
# Every mesh, point and tetrahedral format the tools write, opened by
# independent readers: Debian's meshio (python3-meshio) for every format it
# reads, VTK's own readers (python3-vtk9, what ParaView and 3D Slicer use) for
# .vtp, .vtk and .vtu. Counts and label arrays must agree across formats;
# --frame ras must negate x and y and say so where Slicer looks; unsupported
# extensions and an unknown --frame are usage errors before any input is read.
set -euo pipefail
BIN=$1; SRC=$2
PY=/usr/bin/python3
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
$PY -c "import meshio" 2>/dev/null || { echo "formats_test: python3-meshio missing (scripts/setup installs it)" >&2; exit 1; }
$PY -c "import vtk" 2>/dev/null || { echo "formats_test: python3-vtk9 missing (scripts/setup installs it)" >&2; exit 1; }

# A ball of radius 6 split at x = 9.5 into labels 1 | 2, background 0.
$PY - "$T" <<'PYEOF'
import math, struct, sys
T = sys.argv[1]; n = 20; c = (n - 1) / 2
data = bytearray()
for k in range(n):
    for j in range(n):
        for i in range(n):
            data += struct.pack("B", 0 if math.dist((i, j, k), (c, c, c)) > 6 else (1 if i < 10 else 2))
open(f"{T}/ball.nrrd", "wb").write(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 20 20 20\n"
                                   b"space: left-posterior-superior\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n"
                                   b"space origin: (10,20,30)\nendian: little\nencoding: raw\n\n" + bytes(data))
PYEOF

MC="$BIN/mcinit"; TL="$BIN/tetlabel"
"$MC" "$T/ball.nrrd" "$T/seeds.ply" --junctions -q
"$MC" "$T/ball.nrrd" "$T/seeds.vtp" --junctions -q
"$MC" "$T/ball.nrrd" "$T/seeds.vtk" --junctions -q
# Surface formats, each with one tetrahedral format.
for pair in ply:mesh vtp:vtu vtk:vtk mesh:msh obj: off: stl:; do
  s=${pair%%:*}; v=${pair#*:}
  "$TL" "$T/seeds.ply" --materials "$T/ball.nrrd" -o "$T/if.$s" ${v:+--tets "$T/v.$v"} -q --stats "$T/tl_$s.json"
done
"$TL" "$T/seeds.ply" --materials "$T/ball.nrrd" -o "$T/ras.ply" --tets "$T/ras.vtu" --frame RAS -q
"$TL" "$T/seeds.ply" --materials "$T/ball.nrrd" -o "$T/ras.vtp" --frame ras -q
"$TL" "$T/seeds.ply" --materials "$T/ball.nrrd" -o "$T/ras.vtk" --frame ras -q

$PY - "$T" <<'PYEOF'
import json, sys, warnings
import numpy as np
import meshio
import vtk
from vtk.util.numpy_support import vtk_to_numpy
warnings.simplefilter("ignore")
T = sys.argv[1]
st = json.load(open(f"{T}/tl_ply.json"))["counts"]
NV, NF = st["vertices"], st["faces"]
assert NV > 100 and NF > 200, st

def tris(m):
    return np.concatenate([b.data for b in m.cells if b.type == "triangle"])

ref = meshio.read(f"{T}/if.ply")
assert ref.points.shape == (NV, 3) and tris(ref).shape == (NF, 3), (ref, NV, NF)
la = np.concatenate(ref.cell_data["label_a"]); lb = np.concatenate(ref.cell_data["label_b"])
assert sorted(set(zip(la.tolist(), lb.tolist()))) == [(0, 1), (0, 2), (1, 2)], set(zip(la, lb))
# Legacy .vtk surfaces are UNSTRUCTURED_GRIDs of triangles (meshio reads no legacy
# POLYDATA); VTK's own reader (ParaView, Slicer) judges them below as well.
for ext in ("vtk", "mesh", "obj", "off", "stl"):
    m = meshio.read(f"{T}/if.{ext}")
    t = tris(m)
    assert t.shape == (NF, 3), (ext, t.shape)
    # STL stores float corners (merged again by meshio); the rest keep the points.
    if ext != "stl":
        assert m.points.shape[0] == NV, (ext, m.points.shape)
        assert np.abs(m.points - ref.points).max() < 1e-5, ext  # PLY is float
    if ext == "vtk":
        assert (np.concatenate(m.cell_data["label_a"]).reshape(-1) == la).all() and (np.concatenate(m.cell_data["label_b"]).reshape(-1) == lb).all()
    if ext == "mesh":
        refs = np.concatenate(m.cell_data["medit:ref"])
        pair_id = {(0, 1): 1, (0, 2): 2, (1, 2): 3}
        assert (refs == np.array([pair_id[p] for p in zip(la.tolist(), lb.tolist())])).all(), "medit refs"

# VTK's own readers (ParaView, Slicer).
r = vtk.vtkXMLPolyDataReader(); r.SetFileName(f"{T}/if.vtp"); r.Update(); pd = r.GetOutput()
assert pd.GetNumberOfPoints() == NV and pd.GetNumberOfPolys() == NF, (pd.GetNumberOfPoints(), pd.GetNumberOfPolys())
assert (vtk_to_numpy(pd.GetCellData().GetArray("label_a")) == la).all()
assert (vtk_to_numpy(pd.GetCellData().GetArray("label_b")) == lb).all()
assert np.abs(vtk_to_numpy(pd.GetPoints().GetData()) - ref.points).max() < 1e-5
assert pd.GetFieldData().GetAbstractArray("SPACE").GetValue(0) == "LPS"
r = vtk.vtkUnstructuredGridReader(); r.SetFileName(f"{T}/if.vtk"); r.Update(); ug = r.GetOutput()
assert "SPACE=LPS" in r.GetHeader() and ug.GetNumberOfCells() == NF, ug.GetNumberOfCells()
assert (vtk_to_numpy(ug.GetCellTypesArray()) == vtk.VTK_TRIANGLE).all()
assert (vtk_to_numpy(ug.GetCellData().GetArray("label_a")) == la).all()

# Point sets: the seeds with their scalars in every point format.
s = meshio.read(f"{T}/seeds.ply")
for name in ("junction", "label_a", "label_b"):
    assert name in s.point_data, s.point_data.keys()
sv = meshio.read(f"{T}/seeds.vtk")  # VTK_VERTEX cells
assert sv.points.shape == s.points.shape and np.abs(sv.points - s.points).max() < 1e-5
assert sum(len(b.data) for b in sv.cells if b.type == "vertex") == s.points.shape[0]
assert (sv.point_data["junction"].reshape(-1) == s.point_data["junction"].reshape(-1)).all()
r = vtk.vtkXMLPolyDataReader(); r.SetFileName(f"{T}/seeds.vtp"); r.Update(); sp = r.GetOutput()
assert sp.GetNumberOfPoints() == s.points.shape[0] and sp.GetNumberOfVerts() == s.points.shape[0]
assert (vtk_to_numpy(sp.GetPointData().GetArray("junction")) == s.point_data["junction"]).all()

# Tetrahedra: the same mesh in MEDIT, VTU, VTK and Gmsh.
tets = {}
for ext in ("mesh", "vtu", "vtk", "msh"):
    m = meshio.read(f"{T}/v.{ext}")
    tt = np.concatenate([b.data for b in m.cells if b.type == "tetra"])
    key = {"mesh": "medit:ref", "vtu": "material", "vtk": "material", "msh": "gmsh:physical"}[ext]
    mat = np.concatenate([d for b, d in zip(m.cells, m.cell_data[key]) if b.type == "tetra"]).reshape(-1)
    assert sorted(set(mat.tolist())) == [1, 2], (ext, set(mat.tolist()))
    # Every tetrahedron positively oriented (the writers keep TetGen's order).
    p = m.points[tt]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    assert (vol > 0).all(), (ext, (vol <= 0).sum())
    tets[ext] = (m.points.shape[0], tt.shape[0], np.bincount(mat))
    if ext == "mesh":  # boundary and interface triangles, one reference per label pair
        refs = np.concatenate([d for b, d in zip(m.cells, m.cell_data["medit:ref"]) if b.type == "triangle"])
        assert sorted(set(refs.tolist())) == [1, 2, 3], set(refs.tolist())
        medit_pts = m.points
        medit_pairs = {tuple(sorted(f)): {1: (0, 1), 2: (0, 2), 3: (1, 2)}[r]
                       for f, r in zip(np.concatenate([b.data for b in m.cells if b.type == "triangle"]), refs.tolist())}
        assert len(medit_pairs) == len(refs)
    if ext == "msh":
        # One physical group per material (dim 3) and per label pair (dim 2), every one named.
        names = {n: (int(v[0]), int(v[1])) for n, v in m.field_data.items()}
        assert set(names) == {"material_1", "material_2", "interface_0_1", "interface_0_2", "interface_1_2"}, names
        assert all(d == (3 if n.startswith("material_") else 2) for n, (_, d) in names.items()), names
        assert (mat == np.array([names[f"material_{l}"][0] for l in mat])).all()
        pair_of_tag = {t: tuple(int(x) for x in n.split("_")[1:]) for n, (t, d) in names.items() if d == 2}
        assert not set(pair_of_tag) & {names["material_1"][0], names["material_2"][0]}, names  # no tag is both
        # The triangles: as many as MEDIT's, each in the group of its label pair.
        tri = [(b.data, d.reshape(-1)) for b, d in zip(m.cells, m.cell_data["gmsh:physical"]) if b.type == "triangle"]
        assert tri, [b.type for b in m.cells]
        T3 = np.concatenate([c for c, _ in tri]); tags = np.concatenate([d for _, d in tri])
        assert T3.shape == (len(medit_pairs), 3), (T3.shape, len(medit_pairs))
        assert sorted(set(tags.tolist())) == sorted(pair_of_tag), (set(tags.tolist()), pair_of_tag)
        assert all(len(set(d.tolist())) == 1 for _, d in tri), "one group per triangle block"
        assert np.abs(m.points - medit_pts).max() < 1e-12  # same vertices, same order
        assert {tuple(sorted(f)): pair_of_tag[t] for f, t in zip(T3.tolist(), tags.tolist())} == medit_pairs, "pairs"
first = tets["mesh"]
for ext, v in tets.items():
    assert v[0] == first[0] and v[1] == first[1] and (v[2] == first[2]).all(), (ext, v, first)
r = vtk.vtkXMLUnstructuredGridReader(); r.SetFileName(f"{T}/v.vtu"); r.Update(); ug = r.GetOutput()
assert ug.GetNumberOfCells() == first[1]
assert b"frame LPS SPACE=LPS" in open(f"{T}/v.vtu", "rb").read(200)

# --frame ras: x and y negated, z kept; the frame stated where Slicer reads it.
ras = meshio.read(f"{T}/ras.ply")
assert np.abs(ras.points[:, :2] + ref.points[:, :2]).max() < 1e-5 and np.abs(ras.points[:, 2] - ref.points[:, 2]).max() < 1e-5
assert (tris(ras) == tris(ref)).all()
assert b"comment frame RAS SPACE=RAS\n" in open(f"{T}/ras.ply", "rb").read(4000)
r = vtk.vtkXMLPolyDataReader(); r.SetFileName(f"{T}/ras.vtp"); r.Update()
assert r.GetOutput().GetFieldData().GetAbstractArray("SPACE").GetValue(0) == "RAS"
assert np.abs(vtk_to_numpy(r.GetOutput().GetPoints().GetData())[:, 0] + ref.points[:, 0]).max() < 1e-5
r = vtk.vtkPolyDataReader(); r.SetFileName(f"{T}/ras.vtk"); r.Update()
assert "SPACE=RAS" in r.GetHeader()
rv = meshio.read(f"{T}/ras.vtu")
lv = meshio.read(f"{T}/v.vtu")
assert np.abs(rv.points[:, :2] + lv.points[:, :2]).max() == 0 and (rv.points[:, 2] == lv.points[:, 2]).all()
assert b"frame RAS SPACE=RAS" in open(f"{T}/ras.vtu", "rb").read(200)
print("formats: %d vertices, %d faces, %d tetrahedra in every format" % (NV, NF, first[1]))
PYEOF

# The tetrahedral quality report (meshstats on .mesh) against numpy on meshio's reading.
"$BIN/meshstats" "$T/v.mesh" -o "$T/vq.json" -q --require positive,boundary_manifold,triangles_match
$PY - "$T" <<'PYEOF'
import json, sys
import numpy as np, meshio
T = sys.argv[1]
q = json.load(open(f"{T}/vq.json"))
m = meshio.read(f"{T}/v.mesh")
tt = np.concatenate([b.data for b in m.cells if b.type == "tetra"])
mat = np.concatenate([d for b, d in zip(m.cells, m.cell_data["medit:ref"]) if b.type == "tetra"]).reshape(-1)
p = m.points[tt]
vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6
assert q["overall"]["tets"] == len(tt) and q["positive"] and q["triangles_match"], q
assert abs(q["overall"]["volume"] - vol.sum()) < 1e-9 * vol.sum(), (q["overall"]["volume"], vol.sum())
for l in (1, 2):
    assert abs(q["materials"][str(l)]["volume"] - vol[mat == l].sum()) < 1e-9 * vol.sum()
# Dihedral angles from face normals, all six per tetrahedron.
def normal(a, b, c, opp):
    n = np.cross(b - a, c - a); n /= np.linalg.norm(n, axis=1)[:, None]
    return np.where((np.einsum("ij,ij->i", n, opp - a) > 0)[:, None], -n, n)
N = [normal(p[:, (k + 1) % 4], p[:, (k + 2) % 4], p[:, (k + 3) % 4], p[:, k]) for k in range(4)]
dih = np.degrees(np.pi - np.arccos(np.clip([np.einsum("ij,ij->i", N[k], N[l]) for k in range(4) for l in range(k + 1, 4)], -1, 1)))
assert abs(q["overall"]["dihedral_min"] - dih.min()) < 1e-6 and abs(q["overall"]["dihedral_max"] - dih.max()) < 1e-6
assert q["overall"]["share_under_10"] == (dih.min(axis=0) < 10).mean()
assert sum(q["overall"]["dihedral_hist_10deg"]) == 6 * len(tt)
print("tet quality: %d tetrahedra, dihedral %.2f..%.2f deg, %.1f%% under 10 deg" %
      (len(tt), dih.min(), dih.max(), 100 * (dih.min(axis=0) < 10).mean()))
PYEOF

# Usage errors before any work: the inputs do not even exist, nothing is written.
mkdir "$T/u"
expect_usage() {  # expect_usage REGEX cmd...
  local re=$1; shift
  set +e; "$@" 2> "$T/err"; local rc=$?; set -e
  [ "$rc" -eq 2 ] || { echo "exit $rc, expected 2: $*" >&2; cat "$T/err" >&2; exit 1; }
  grep -Eq "$re" "$T/err" || { echo "message does not match /$re/:" >&2; cat "$T/err" >&2; exit 1; }
  [ -z "$(ls -A "$T/u")" ] || { echo "files left: $(ls -A "$T/u")" >&2; exit 1; }
}
N="$T/nonexistent"
expect_usage 'tetlabel: usage error: --tets ".*/v\.obj": unknown tetrahedral mesh extension "\.obj"; expected one of \.mesh \.vtu \.vtk \.msh' \
  "$TL" "$N.ply" --materials "$N.nrrd" -o "$T/u/if.ply" --tets "$T/u/v.obj"
expect_usage 'tetlabel: usage error: --output ".*/if\.txt": unknown mesh extension "\.txt"' \
  "$TL" "$N.ply" --implicit sphere -o "$T/u/if.txt"
expect_usage 'tetlabel: usage error: --material-surfaces ".*/m0\.xyz": unknown mesh extension' \
  "$TL" "$N.ply" --materials "$N.nrrd" -o "$T/u/if.ply" --material-surfaces "$T/u/m%d.xyz"
expect_usage 'mcinit: usage error: output ".*/s\.mesh": unknown point set extension "\.mesh"; expected one of \.ply \.vtp \.vtk' \
  "$MC" "$N.nrrd" "$T/u/s.mesh" --junctions
expect_usage 'usage error: --frame: .*xyz' "$TL" "$N.ply" --implicit sphere -o "$T/u/if.ply" --frame xyz
expect_usage 'usage error: --stats ".*/st\.txt": unknown JSON extension' "$MC" "$N.nrrd" "$T/u/s.ply" --junctions --stats "$T/u/st.txt"
expect_usage 'render: usage error: --output ".*/r\.jpg": unknown image extension' "$BIN/render" "$N.ply" -o "$T/u/r.jpg"
expect_usage 'meshstats: usage error: --output ".*/q\.txt": unknown JSON extension' "$BIN/meshstats" "$N.ply" -o "$T/u/q.txt"
echo "formats_test: ok"
