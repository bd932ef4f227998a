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
