# mesh_surface() and mesh_materials(): the Chapter 5 and 6 pipelines through
# the Python API, checked against exact geometry (a sphere; a cube of two
# materials whose interface is a plane), plus tetrahedra and meshio.
import math
import os

import numpy as np
import pytest

import particlemesh as pm
from conftest import edge_counts, interrupt_during, read_ply, sphere_distance, triangle_areas, two_material_cube

H, R, N = 0.5, 4.0, 25
ORIGIN = (-6.0, -6.0, -6.0)


def test_grey_sphere_surface():
    d = sphere_distance(n=N, h=H, radius=R, origin=ORIGIN)
    m = pm.mesh_surface(d, iso=0.0, voxel_spacing=H, origin=ORIGIN, progress=False)
    assert m.kind == "grey"
    radius = np.linalg.norm(m.points, axis=1)
    # Vertices on the B-spline isosurface, h^2/(3R) inside the sphere (see
    # test_sample); improvement keeps them on it.
    shift = H * H / (3 * R)
    assert abs(np.mean(radius) - (R - shift)) < 0.25 * shift
    assert np.max(np.abs(radius - (R - shift))) < shift
    # Closed manifold of genus 0: every edge in two triangles, V - E + F = 2.
    counts = edge_counts(m.triangles)
    assert np.all(counts == 2)
    assert len(m.points) - len(counts) + len(m.triangles) == 2
    # Inscribed in the sphere of radius r = R - shift: its area and volume are
    # below the sphere's, and above them times (d/r)^2 and (d/r)^3, d = the
    # smallest distance from the centre to a triangle's plane (the radial
    # projection of a triangle onto the sphere grows it at most by (r/d)^2).
    r = R - shift
    a, b, c = (m.points[m.triangles[:, i]] for i in range(3))
    cr = np.cross(b - a, c - a)
    d_plane = np.abs(np.einsum("ij,ij->i", a, cr)) / np.linalg.norm(cr, axis=1)
    q = d_plane.min() / r
    assert 0.8 < q < 1
    area = triangle_areas(m.points, m.triangles).sum()
    assert 4 * math.pi * r * r * q * q < area < 4 * math.pi * r * r * (1 + 1e-4)
    # Outward orientation: the signed volume is positive, between the same bounds.
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6
    assert 4 / 3 * math.pi * r ** 3 * q ** 3 < vol < 4 / 3 * math.pi * r ** 3 * (1 + 1e-4)
    assert np.all(m.pairs == [1, 0])
    assert m.tetrahedra is None  # only when asked
    # to_meshio(frame="ras"), as the tools' --frame ras: x and y negated, same triangles.
    meshio = pytest.importorskip("meshio")
    ras = m.to_meshio(frame="ras")
    np.testing.assert_array_equal(ras.points, m.points * [-1, -1, 1])
    np.testing.assert_array_equal(ras.point_data["normals"], m.normals * [-1, -1, 1])
    assert np.array_equal(ras.cells[0].data, m.triangles)
    with pytest.raises(ValueError, match='frame: "xyz" is unknown'):
        m.to_meshio(frame="xyz")


def test_mask_sphere_surface_and_tets():
    d = sphere_distance(n=N, h=H, radius=R, origin=ORIGIN)
    mask = (d < 0).astype(np.uint8)
    m = pm.mesh_surface(mask, voxel_spacing=H, origin=ORIGIN, tetrahedra=True, progress=False)
    assert m.kind == "mask"
    # The mask's surface crosses the grid edges from inside to outside nodes,
    # which cross the sphere: it is within one voxel of it; tightening with
    # radius h keeps the surface between the mask's opening and closing.
    radius = np.linalg.norm(m.points, axis=1)
    assert np.max(np.abs(radius - R)) < H
    assert np.all(edge_counts(m.triangles) == 2)
    t = m.tetrahedra
    assert t.tets.shape[1] == 4 and len(t.tets) == len(t.labels) and np.all(t.labels == 1)
    # The inside tetrahedra fill the (unimproved) surface: volume near the ball's.
    p = t.points
    a, b, c, e = (p[t.tets[:, i]] for i in range(4))
    tv = np.abs(np.einsum("ij,ij->i", b - a, np.cross(c - a, e - a))).sum() / 6
    assert abs(tv - 4 / 3 * math.pi * R ** 3) < 4 * math.pi * R * R * H
    meshio = pytest.importorskip("meshio")
    mm = m.to_meshio()
    assert isinstance(mm, meshio.Mesh) and mm.cells[0].type == "triangle"
    assert np.array_equal(mm.cells[0].data, m.triangles)
    assert len(t.to_meshio().cells[0].data) == len(t.tets)


@pytest.fixture(scope="module")
def cube():
    # Voxel spacing 0.5 and an origin: world units everywhere.
    h, origin = 0.5, (10.0, -2.0, 3.0)
    lab = two_material_cube()
    return h, origin, pm.mesh_materials(lab, voxel_spacing=h, origin=origin, radius=h, tetrahedra=True,
                                        progress=False)


def test_two_material_cube_interface(cube):
    h, origin, m = cube
    assert sorted(m.label_pairs) == [(0, 1), (0, 2), (1, 2)]
    assert m.outside_label == 0
    sel = np.all(m.pairs == [1, 2], axis=1)
    tri = m.triangles[sel]
    x = m.points[np.unique(tri), 0]
    # The 1|2 interface is the plane halfway between voxels 9 and 10; both
    # distance fields are exact planes there (Catmull-Rom reproduces them).
    plane = origin[0] + 9.5 * h
    assert np.median(np.abs(x - plane)) < 1e-3 * h
    assert np.max(np.abs(x - plane)) < h
    # Its area: the cube's 12 x 12 voxel cross-section, less at most a band of
    # the tightening radius along its border where the three materials meet.
    side = 12 * h
    area = triangle_areas(m.points, tri).sum()
    assert (side - 2 * h) ** 2 < area <= side ** 2 * 1.001
    # Normals from label_a (1, at smaller x) into label_b (2).
    a, b, c = (m.points[tri[:, i]] for i in range(3))
    n = np.cross(b - a, c - a).sum(axis=0)
    assert n[0] > 0.99 * np.linalg.norm(n)
    # Each material's closed surface, and the tetrahedra carry both labels.
    for label in (1, 2):
        pts, tris = m.surfaces[label]
        assert np.all(edge_counts(tris) == 2)
    assert set(np.unique(m.tetrahedra.labels)) == {1, 2}


def test_materials_meshio(cube):
    meshio = pytest.importorskip("meshio")
    _, _, m = cube
    mm = m.to_meshio()
    assert isinstance(mm, meshio.Mesh)
    assert np.array_equal(mm.cell_data["label_a"][0], m.pairs[:, 0])
    assert np.all(mm.cell_data["label_a"][0] < mm.cell_data["label_b"][0])


# --- the library pipelines give what the Makefiles give -------------------------

def _make(target, **variables):
    import shutil
    import subprocess
    src = os.environ.get("PM_SOURCE_DIR")
    bindir = os.environ.get("PM_BIN")
    if not src or not bindir or not os.path.exists(os.path.join(bindir, "tetlabel")) or not shutil.which("make"):
        pytest.skip("needs make and the tools (PM_SOURCE_DIR, PM_BIN, set by CTest)")
    args = ["make", "-s", "-f", os.path.join(src, "Makefile.pipeline"), target, f"BIN={bindir}"]
    args += [f"{k}={v}" for k, v in variables.items()]
    r = subprocess.run(args, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr


def _nifti(path, array, spacing, origin):
    nib = pytest.importorskip("nibabel")
    affine = np.diag([spacing, spacing, spacing, 1.0])
    affine[:3, 3] = origin
    img = nib.Nifti1Image(array, affine)
    img.set_sform(affine, code=1)
    nib.save(img, str(path))


def test_mesh_surface_is_makefile_ch5(tmp_path):
    d = sphere_distance(n=N, h=H, radius=R, origin=ORIGIN)
    _nifti(tmp_path / "ball.nii", (d < 0).astype(np.uint8), H, ORIGIN)
    _make("surface", INPUT=tmp_path / "ball.nii", OUT=tmp_path / "out")
    points, triangles, _ = read_ply(tmp_path / "out" / "surface.ply")
    m = pm.mesh_surface(pm.read_volume(tmp_path / "ball.nii"), progress=False)
    # Same triangles; vertices equal up to the PLY's float32 rounding.
    assert np.array_equal(triangles, m.triangles)
    np.testing.assert_allclose(points, m.points, rtol=0, atol=1e-6 * np.abs(m.points).max())


@pytest.mark.parametrize("ma_side", ["inside", "both"])
def test_mesh_materials_is_makefile_ch6(tmp_path, ma_side):
    _nifti(tmp_path / "cube.nii", two_material_cube().astype(np.int16), 1.0, (0.0, 0.0, 0.0))
    _make("materials", INPUT=tmp_path / "cube.nii", OUT=tmp_path / "out", MA_SIDE=ma_side)
    points, triangles, props = read_ply(tmp_path / "out" / "interfaces.ply")
    m = pm.mesh_materials(pm.read_volume(tmp_path / "cube.nii"), ma_side=ma_side, progress=False)
    assert np.array_equal(triangles, m.triangles)
    assert np.array_equal(np.stack([props["label_a"], props["label_b"]], axis=1), m.pairs)
    np.testing.assert_allclose(points, m.points, rtol=0, atol=1e-6 * np.abs(m.points).max())


def test_mesh_materials_refuses_an_unknown_medial_axis_side():
    with pytest.raises(ValueError, match=r'MA_SIDE "up"; expected inside, outside or both'):
        pm.mesh_materials(two_material_cube(), ma_side="up", progress=False)


def test_ctrl_c_stops_a_pipeline():
    # Ctrl-C in the middle of mesh_materials (GIL released, no callback): the
    # stage running checks Python's signals and the call ends with
    # KeyboardInterrupt; a run afterwards works.
    lab = two_material_cube()
    interrupt_during(lambda: pm.mesh_materials(lab, voxel_spacing=0.5, progress=False))
    m = pm.mesh_materials(lab, voxel_spacing=0.5, progress=False)
    assert sorted(m.label_pairs) == [(0, 1), (0, 2), (1, 2)]


def test_labels_of_a_label_map():
    # labels=[2]: the mask of material 2 of the cube, voxels i 10..15, j and k
    # 4..15 (spacing 0.5): its surface lies within a voxel of that box.
    lab = two_material_cube()
    m = pm.mesh_surface(lab, labels=[2], voxel_spacing=0.5, progress=False)
    assert m.kind == "mask" and np.all(edge_counts(m.triangles) == 2)
    lo, hi = m.points.min(axis=0), m.points.max(axis=0)
    np.testing.assert_allclose(lo, np.array([10, 4, 4]) * 0.5, atol=0.5)
    np.testing.assert_allclose(hi, np.array([15, 15, 15]) * 0.5, atol=0.5)
