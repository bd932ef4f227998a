#!/usr/bin/env bash
# Tetrahedral meshes written by other tools, read by ours (issue 19): meshio
# (every variant it writes for .vtu .vtk .msh .mesh) and VTK's own writers
# (what ParaView and 3D Slicer save: appended base64/raw, zlib or none,
# UInt64 headers; legacy 5.1 binary) make a box of Kuhn tetrahedra in three
# materials. meshstats must find the same tetrahedra, materials and volume as
# numpy, pass a --require the mesh meets and fail (exit 3) one it does not;
# tetlabel's own four formats must give one report; render --clip must show
# both materials on the cut and none of the removed side.
set -euo pipefail
BIN=$1; SRC=$2
PY=/usr/bin/python3
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
$PY -c "import meshio, vtk" 2>/dev/null || { echo "tet_formats_test: python3-meshio or python3-vtk9 missing (scripts/setup installs them)" >&2; exit 1; }
MS="$BIN/meshstats"; RD="$BIN/render"

# ---- files by meshio and VTK, and what they hold ----
$PY - "$T" <<'PYEOF'
import json, sys, warnings
import numpy as np
import meshio, vtk
from vtk.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
warnings.simplefilter("ignore")
T = sys.argv[1]
# [0, 2] x [0, 1.5] x [0, 1] in cubes of 0.25 (origin moved so coordinates are not short):
# material 3 beyond x = 1.5, else 1 below y = 0.75 and 2 above.
nx, ny, nz, h = 8, 6, 4, 0.25
o = np.array([10.0, -4.0, 2.5])
pts = np.array([[i * h, j * h, k * h] for k in range(nz + 1) for j in range(ny + 1) for i in range(nx + 1)]) + o
vid = lambda i, j, k: (k * (ny + 1) + j) * (nx + 1) + i
kuhn = [(0, 1, 3, 7), (0, 1, 7, 5), (0, 2, 7, 3), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 7, 6)]
tets = []
for k in range(nz):
    for j in range(ny):
        for i in range(nx):
            for q in kuhn:
                c = [vid(i + (v & 1), j + ((v >> 1) & 1), k + (v >> 2)) for v in q]
                p = pts[c]
                if np.dot(p[1] - p[0], np.cross(p[2] - p[0], p[3] - p[0])) < 0: c[2], c[3] = c[3], c[2]
                tets.append(c)
tets = np.array(tets)
cen = pts[tets].mean(axis=1) - o
mat = np.where(cen[:, 0] > 1.5, 3, np.where(cen[:, 1] < 0.75, 1, 2)).astype(np.int32)
p = pts[tets]
vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6
assert (vol > 0).all()
tris = np.array([[vid(0, 0, 0), vid(1, 0, 0), vid(0, 1, 0)]])  # one triangle, for the mixed-cell files
expect = {"tets": len(tets), "volume": float(vol.sum()),
          "materials": {str(m): int((mat == m).sum()) for m in (1, 2, 3)}}
json.dump(expect, open(f"{T}/expect.json", "w"))

mixed = meshio.Mesh(pts, [("tetra", tets), ("triangle", tris)],
                    cell_data={"material": [mat, np.array([9], np.int32)]})
mixed.write(f"{T}/meshio_zlib.vtu")
mixed.write(f"{T}/meshio_ascii.vtu", binary=False)
mixed.write(f"{T}/meshio_raw.vtu", compression=None)
mixed.write(f"{T}/meshio_51b.vtk")
mixed.write(f"{T}/meshio_51a.vtk", binary=False)
mixed.write(f"{T}/meshio_42b.vtk", file_format="vtk42")
mixed.write(f"{T}/meshio_42a.vtk", file_format="vtk42", binary=False)
medit = meshio.Mesh(pts, [("tetra", tets), ("triangle", tris)],
                    cell_data={"medit:ref": [mat, np.array([9])]})
medit.write(f"{T}/meshio.mesh")
# Gmsh 4.1: meshio keeps physical tags only through $Entities, which it writes from
# gmsh:dim_tags (one volume entity 100 + m per material m, one cell block each).
node_entity = np.zeros(len(pts), int)
for c, m in zip(tets, mat): node_entity[c] = 100 + m
g = meshio.Mesh(pts, [("tetra", tets[mat == m]) for m in (1, 2, 3)],
                cell_data={"gmsh:physical": [np.full((mat == m).sum(), m) for m in (1, 2, 3)],
                           "gmsh:geometrical": [np.full((mat == m).sum(), 100 + m) for m in (1, 2, 3)]},
                point_data={"gmsh:dim_tags": np.stack([np.full(len(pts), 3), node_entity], axis=1)},
                field_data={f"material_{m}": np.array([m, 3]) for m in (1, 2, 3)})
g.write(f"{T}/meshio_41b.msh", file_format="gmsh")
g.write(f"{T}/meshio_41a.msh", file_format="gmsh", binary=False)
back = meshio.read(f"{T}/meshio_41a.msh")  # meshio itself reads the materials back
assert sorted(np.concatenate(back.cell_data["gmsh:physical"]).tolist()) == sorted(mat.tolist())
g22 = meshio.Mesh(pts, [("tetra", tets), ("triangle", tris)],
                  cell_data={"gmsh:physical": [mat, np.array([9])], "gmsh:geometrical": [mat, np.array([9])]})
g22.write(f"{T}/meshio_22a.msh", file_format="gmsh22", binary=False)
g22.write(f"{T}/meshio_22b.msh", file_format="gmsh22")

ug = vtk.vtkUnstructuredGrid()
vp = vtk.vtkPoints(); vp.SetData(numpy_to_vtk(pts, deep=True)); ug.SetPoints(vp)
cells = vtk.vtkCellArray()
cells.SetCells(len(tets), numpy_to_vtkIdTypeArray(np.hstack([np.full((len(tets), 1), 4), tets]).astype(np.int64).ravel(), deep=True))
ug.SetCells(vtk.VTK_TETRA, cells)
arr = numpy_to_vtk(mat, deep=True); arr.SetName("material"); ug.GetCellData().AddArray(arr)
def xml(name, **kw):
    w = vtk.vtkXMLUnstructuredGridWriter(); w.SetInputData(ug); w.SetFileName(f"{T}/{name}")
    if kw.get("mode") == "binary": w.SetDataModeToBinary()
    if kw.get("mode") == "ascii": w.SetDataModeToAscii()
    if kw.get("raw"): w.EncodeAppendedDataOff()
    if kw.get("nocompress"): w.SetCompressorTypeToNone()
    if kw.get("uint64"): w.SetHeaderTypeToUInt64()
    if kw.get("big"): w.SetByteOrderToBigEndian()
    assert w.Write() == 1, name
xml("vtk_default.vtu")
xml("vtk_raw.vtu", raw=True)
xml("vtk_raw_plain.vtu", raw=True, nocompress=True)
xml("vtk_binary_u64.vtu", mode="binary", uint64=True)
xml("vtk_big.vtu", raw=True, nocompress=True, big=True)
xml("vtk_ascii.vtu", mode="ascii")
w = vtk.vtkUnstructuredGridWriter(); w.SetInputData(ug); w.SetFileName(f"{T}/vtk_legacy_b.vtk"); w.SetFileTypeToBinary(); w.Write()
w = vtk.vtkUnstructuredGridWriter(); w.SetInputData(ug); w.SetFileName(f"{T}/vtk_legacy_a.vtk"); w.Write()
PYEOF

# ---- meshstats reads each: same counts, materials and volume; --require gates ----
n=0
for f in "$T"/meshio* "$T"/vtk_*; do
  "$MS" -q "$f" -o "$T/q.json" --require "dihedral_min>=12,dihedral_max<=160,share_25_140>=0.99,positive,boundary_manifold" ||
    { echo "meshstats $f: exit $? on requirements the mesh meets" >&2; exit 1; }
  $PY - "$T/q.json" "$T/expect.json" "$f" <<'PYEOF'
import json, sys
q, e, f = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), sys.argv[3]
assert q["overall"]["tets"] == e["tets"], (f, q["overall"]["tets"], e["tets"])
assert {k: v["tets"] for k, v in q["materials"].items()} == e["materials"], (f, q["materials"].keys())
assert abs(q["overall"]["volume"] - e["volume"]) < 1e-9 * e["volume"], (f, q["overall"]["volume"], e["volume"])
# Kuhn tetrahedra: dihedral angles of 45, 60 and 90 degrees only.
assert abs(q["overall"]["dihedral_min"] - 45) < 1e-6 and abs(q["overall"]["dihedral_max"] - 90) < 1e-6, f
assert q["overall"]["share_25_140"] == 1.0 and q["positive"] and q["boundary_manifold"], f
PYEOF
  set +e
  "$MS" -q "$f" --require "rr_mean>=0.8,dihedral_min>=12" 2>"$T/err"; rc=$?
  set -e
  [ $rc -eq 3 ] || { echo "meshstats $f --require rr_mean>=0.8: exit $rc, expected 3" >&2; exit 1; }
  grep -q "1 requirement(s) not met: rr_mean>=0.8 (have 0.7" "$T/err" || { cat "$T/err" >&2; exit 1; }
  n=$((n + 1))
done
[ $n -eq 20 ] || { echo "tet_formats_test: $n files checked, expected 20" >&2; exit 1; }

# ---- tetlabel's four formats give one report ----
$PY - "$T" <<'PYEOF'
import math, struct, sys
T = sys.argv[1]; n = 16; c = (n - 1) / 2
data = bytearray()
for k in range(n):
    for j in range(n):
        for i in range(n):
            data += struct.pack("B", 0 if math.dist((i, j, k), (c, c, c)) > 5 else (1 if i < 8 else 2))
open(f"{T}/ball.nrrd", "wb").write(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 16 16 16\n"
                                   b"space: left-posterior-superior\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n"
                                   b"space origin: (10,20,30)\nendian: little\nencoding: raw\n\n" + bytes(data))
PYEOF
"$BIN/mcinit" "$T/ball.nrrd" "$T/seeds.ply" --junctions -q
for ext in mesh vtu vtk msh; do
  "$BIN/tetlabel" "$T/seeds.ply" --materials "$T/ball.nrrd" -o "$T/if.ply" --tets "$T/tl.$ext" --frame ras -q
  "$MS" -q "$T/tl.$ext" -o "$T/tl_$ext.json"
done
$PY - "$T" <<'PYEOF'
import json, sys
T = sys.argv[1]
r = {e: json.load(open(f"{T}/tl_{e}.json")) for e in ("mesh", "vtu", "vtk", "msh")}
ref = r["mesh"]
assert ref["overall"]["tets"] > 100 and set(ref["materials"]) == {"1", "2"}, ref["materials"].keys()
for e, q in r.items():
    for k in ("tets", "volume", "dihedral_min", "dihedral_max", "rr_mean", "share_25_140"):
        assert abs(q["overall"][k] - ref["overall"][k]) <= 1e-12 * max(1, abs(ref["overall"][k])), (e, k)
    assert {m: v["tets"] for m, v in q["materials"].items()} == {m: v["tets"] for m, v in ref["materials"].items()}, e
    assert q["boundary_faces"] == ref["boundary_faces"] and q["interface_faces"] == ref["interface_faces"], e
PYEOF

# ---- render: a crinkle clip of each reader's mesh ----
for f in meshio_zlib.vtu meshio_51b.vtk meshio_41b.msh meshio.mesh vtk_default.vtu; do
  "$RD" -q "$T/$f" -o "$T/cut.png" --clip x:0.5 --legend --edges --size 240x240
  "$RD" -q "$T/$f" -o "$T/whole.png" --size 240x240
  $PY - "$T/cut.png" "$T/whole.png" "$f" <<'PYEOF'
import struct, sys, zlib
def pixels(path):
    data = open(path, "rb").read()
    pos, idat = 8, b""
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if kind == b"IHDR": w, h = struct.unpack(">II", data[pos + 8:pos + 16])
        if kind == b"IDAT": idat += data[pos + 8:pos + 8 + n]
        pos += 12 + n
    raw, stride, out, prev, i = zlib.decompress(idat), 3 * w, [], bytearray(3 * w), 0
    for _ in range(h):
        f, line = raw[i], bytearray(raw[i + 1:i + 1 + stride]); i += 1 + stride
        for x in range(stride):
            a = line[x - 3] if x >= 3 else 0
            b, c = prev[x], (prev[x - 3] if x >= 3 else 0)
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c; pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else (b if pb <= pc else c))) & 255
        out += [tuple(line[x:x + 3]) for x in range(0, stride, 3)]; prev = line
    return out
# The categorical palette (pm::category_color) of materials 1, 2, 3.
palette = {1: (1.000, 0.498, 0.055), 2: (0.173, 0.627, 0.173), 3: (0.839, 0.153, 0.157)}
def count(px, c):  # pixels that are a shade k * c of colour c
    n = 0
    for r, g, b in px:
        v = (r / 255, g / 255, b / 255)
        k = sum(a * b for a, b in zip(v, c)) / sum(a * a for a in c)
        n += k > 0.2 and sum((a - k * b) ** 2 for a, b in zip(v, c)) ** 0.5 < 0.02
    return n
cut, whole, f = pixels(sys.argv[1]), pixels(sys.argv[2]), sys.argv[3]
cc = {m: count(cut, c) for m, c in palette.items()}
wc = {m: count(whole, c) for m, c in palette.items()}
assert cc[1] > 800 and cc[2] > 800 and cc[3] == 0, (f, "cut", cc)
assert wc[3] > 800, (f, "whole", wc)
PYEOF
done

# ---- bad input ----
expect_fail() {  # expect_fail CODE REGEX cmd...
  local code=$1 re=$2; shift 2
  set +e; "$@" 2>"$T/err" >/dev/null; local rc=$?; set -e
  [ $rc -eq "$code" ] && grep -Eq "$re" "$T/err" || { echo "expected exit $code and /$re/ from $*; got $rc:" >&2; cat "$T/err" >&2; exit 1; }
}
head -c 3000 "$T/vtk_default.vtu" > "$T/cut.vtu"
expect_fail 1 "meshstats: error: read_vtu: .*cut.vtu.*line [0-9]+: .*(truncated|not well-formed)" "$MS" "$T/cut.vtu"
head -c 2000 "$T/meshio_41b.msh" > "$T/cut.msh"
expect_fail 1 "meshstats: error: read_gmsh: .*cut.msh.*line [0-9]+: .*truncated" "$MS" "$T/cut.msh"
$PY -c "
import meshio, numpy as np
meshio.Mesh(np.eye(4)[:, :3], [('tetra', np.array([[0, 1, 2, 3]]))]).write('$T/ansys.msh')"
expect_fail 1 "meshstats: error: read_gmsh: .*ansys.msh.*ANSYS" "$MS" "$T/ansys.msh"
expect_fail 1 "render: error: read_gmsh: .*ansys.msh.*ANSYS" "$RD" "$T/ansys.msh" -o "$T/x.png"
expect_fail 2 "meshstats: usage error: requirement \"dihedral_min>=abc\": expected a number" "$MS" "$T/meshio.mesh" --require "dihedral_min>=abc"
expect_fail 2 "render: usage error: render: --color-by \"pair\" for a tetrahedral mesh" "$RD" "$T/meshio.mesh" -o "$T/x.png" --color-by pair
expect_fail 1 "render: error: render: the clip \"x:0\" removes every tetrahedron" "$RD" "$T/meshio.mesh" -o "$T/x.png" --clip x:0
[ ! -e "$T/x.png" ] || { echo "a failed render left x.png" >&2; exit 1; }
echo "tet_formats_test: ok ($n files from meshio and VTK)"
