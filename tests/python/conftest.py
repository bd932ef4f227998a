# Shared fixtures of the particlemesh Python tests: analytic volumes.
# The module comes from PYTHONPATH (build/python, set by CTest); without it
# every test is skipped.
import os
import signal
import sys
import threading

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
    """(vertices V x 3, faces F x 3, face properties {name: F}) of a PLY the
    tools wrote, read by meshio (the independent reader; the tools write
    meshes with face properties as ASCII PLY, which meshio reads)."""
    meshio = pytest.importorskip("meshio")
    m = meshio.read(str(path))
    tri = [i for i, c in enumerate(m.cells) if c.type == "triangle"]
    assert len(tri) == 1, f"{path}: expected one triangle block, got {[c.type for c in m.cells]}"
    props = {k: np.asarray(v[tri[0]]).astype(np.int64) for k, v in m.cell_data.items()}
    return m.points.astype(np.float64), m.cells[tri[0]].data.astype(np.int64), props


def interrupt_during(call):
    """Run call() on this (the main) thread and press Ctrl-C while it runs:
    another thread sends SIGINT as soon as it gets the GIL. With a switch
    interval of 1000 s this thread keeps the GIL until the call releases it
    for its long computation, so the signal arrives while libcore runs and
    only libcore's cancellation check (Python's signal check) can stop it.
    Asserts that call() raised KeyboardInterrupt."""
    ready = threading.Event()

    def interrupt():
        ready.wait()
        os.kill(os.getpid(), signal.SIGINT)

    t = threading.Thread(target=interrupt)
    old = sys.getswitchinterval()
    t.start()
    sys.setswitchinterval(1000)
    try:
        ready.set()
        with pytest.raises(KeyboardInterrupt):
            call()
    finally:
        sys.setswitchinterval(old)
        t.join()
