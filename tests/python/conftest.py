# Shared fixtures of the particlemesh Python tests: analytic volumes.
# The module comes from PYTHONPATH (build/python, set by CTest); without it
# every test is skipped.
import numpy as np
import pytest

pm = pytest.importorskip("particlemesh", reason="the particlemesh module is not built (PM_PYTHON)")


def sphere_distance(n=33, h=0.5, radius=5.0, origin=(-8.0, -8.0, -8.0), centre=(0.0, 0.0, 0.0)):
    """Signed distance |x - centre| - radius at the nodes of an n^3 grid of spacing h (world units):
    node [i, j, k] sits at origin + h (i, j, k)."""
    ax = [origin[a] + h * np.arange(n) - centre[a] for a in range(3)]
    x, y, z = np.meshgrid(*ax, indexing="ij")
    return np.sqrt(x * x + y * y + z * z) - radius


def two_material_cube(n=20, lo=4, hi=15, split=10):
    """Label map: 0 outside the voxel cube [lo, hi]^3, inside it 1 for i < split and 2 for i >= split."""
    lab = np.zeros((n, n, n), dtype=np.int32)
    lab[lo:hi + 1, lo:hi + 1, lo:hi + 1] = 1
    lab[split:hi + 1, lo:hi + 1, lo:hi + 1] = 2
    return lab


def triangle_areas(points, triangles):
    a, b, c = (points[triangles[:, i]] for i in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def edge_counts(triangles):
    e = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return counts


def read_ply(path):
    """(vertices V x 3, faces F x 3, face properties {name: F}) of a binary
    little-endian PLY as particlemesh writes it (float vertex properties,
    uchar-int face lists, int face properties). meshio 7 cannot read PLY face
    properties, hence this small reader."""
    types = {"float": "<f4", "double": "<f8", "int": "<i4", "uchar": "u1", "uint": "<u4"}
    with open(path, "rb") as f:
        assert f.readline().strip() == b"ply"
        elements, cur = [], None
        while True:
            line = f.readline().decode().split()
            if line[0] == "end_header":
                break
            if line[0] == "format":
                assert line[1] == "binary_little_endian"
            if line[0] == "element":
                cur = (line[1], int(line[2]), [])
                elements.append(cur)
            if line[0] == "property":
                cur[2].append(("list", line[2], line[3], line[4]) if line[1] == "list" else (types[line[1]], line[2]))
        data = f.read()
    off, verts, faces, props = 0, None, None, {}
    for name, count, fields in elements:
        if name == "vertex":
            dt = np.dtype([(p[1], p[0]) for p in fields])
            v = np.frombuffer(data, dt, count, off)
            off += dt.itemsize * count
            verts = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)
        elif name == "face":
            assert fields[0][:3] == ("list", "uchar", "int")
            dt = np.dtype([("n", "u1"), ("idx", "<i4", (3,))] + [(p[1], p[0]) for p in fields[1:]])
            fa = np.frombuffer(data, dt, count, off)
            off += dt.itemsize * count
            assert np.all(fa["n"] == 3)
            faces = fa["idx"].astype(np.int64)
            props = {p[1]: fa[p[1]].astype(np.int64) for p in fields[1:]}
    return verts, faces, props
