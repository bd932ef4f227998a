# sample(): the particle system of Chapter 3 on a sphere's distance volume,
# the same analytic check as the C++ tests, through the Python API.
import math
import os
import signal
import sys
import threading

import numpy as np
import pytest

import particlemesh as pm
from conftest import interrupt_during, sphere_distance

H, R, N = 0.5, 5.0, 33
ORIGIN = (-7.0, -9.0, -8.0)
CENTRE = (1.0, -1.0, 0.5)


@pytest.fixture(scope="module")
def sphere():
    return sphere_distance(n=N, h=H, radius=R, origin=ORIGIN, centre=CENTRE)


def test_sphere_radius_normals_and_count(sphere):
    s = 1.0
    r = pm.sample(sphere, iso=0.0, spacing=s, voxel_spacing=H, origin=ORIGIN, tolerance=1e-4, progress=False)
    rel = r.points - np.array(CENTRE)
    radius = np.linalg.norm(rel, axis=1)
    # The cubic B-spline approximates: per axis it adds h^2/6 times the
    # second derivative, so F ~ d + h^2/6 lap(d) = d + h^2/(3R) on a sphere,
    # and F = 0 sits h^2/(3R) inside the true sphere (0.0167 here).
    shift = H * H / (3 * R)
    assert abs(np.mean(radius) - (R - shift)) < 0.25 * shift
    assert np.max(np.abs(radius - R)) < 2 * shift
    # Normals: outward and radial.
    cosines = np.sum(r.normals * rel, axis=1) / radius
    assert np.min(cosines) > 1 - 1e-3
    # Hexagonal packing: N = area / (s^2 sqrt(3)/2), within 10% (as the C++ test).
    expected = 4 * math.pi * R * R / (s * s * math.sqrt(3) / 2)
    assert abs(len(r.points) - expected) < 0.1 * expected
    assert r.spacing.shape == (len(r.points),)
    assert np.allclose(r.spacing, s)


def test_world_units_follow_voxel_spacing(sphere):
    # The same voxels with twice the spacing are a sphere of twice the radius
    # about the scaled centre.
    o2 = tuple(2 * o for o in ORIGIN)
    r = pm.sample(sphere * 2, iso=0.0, spacing=2.0, voxel_spacing=2 * H, origin=o2, progress=False)
    radius = np.linalg.norm(r.points - 2 * np.array(CENTRE), axis=1)
    assert abs(np.mean(radius) - 2 * R) < 2 * (2 * H) ** 2 / (3 * 2 * R)


def test_volume_object_carries_its_geometry(sphere):
    vol = pm.Volume(array=sphere, origin=np.array(ORIGIN), spacing=np.full(3, H))
    a = pm.sample(vol, iso=0.0, spacing=1.5, progress=False)
    b = pm.sample(sphere, iso=0.0, spacing=1.5, origin=ORIGIN, voxel_spacing=H, progress=False)
    assert np.array_equal(a.points, b.points)


def test_progress_callback_and_meshio(sphere):
    calls = []
    r = pm.sample(sphere, iso=0.0, spacing=1.5, voxel_spacing=H, origin=ORIGIN,
                  progress=lambda label, done, total, detail: calls.append((label, done, total)))
    assert calls, "the progress callback was never called"
    assert all(done <= total for _, done, total in calls)
    meshio = pytest.importorskip("meshio")
    m = r.to_meshio()
    assert isinstance(m, meshio.Mesh)
    assert np.array_equal(m.points, r.points)
    assert np.array_equal(m.point_data["normals"], r.normals)


def test_exception_in_callback_stops_the_run(sphere):
    class Stop(Exception):
        pass

    def cb(label, done, total, detail):
        if done >= 3:
            raise Stop("enough")

    with pytest.raises(Stop, match="enough"):
        pm.sample(sphere, iso=0.0, spacing=0.5, voxel_spacing=H, origin=ORIGIN, tolerance=1e-12, max_iters=3000,
                  progress=cb)
    # and the module still works afterwards
    assert len(pm.sample(sphere, iso=0.0, spacing=2.0, voxel_spacing=H, origin=ORIGIN, progress=False).points) > 50


def test_ctrl_c_stops_the_run(sphere):
    # Ctrl-C while the engine runs with the GIL released and no Python
    # callback: the engine's cancellation check runs Python's signal handler,
    # the call ends with KeyboardInterrupt, and the module is left as it was:
    # the next run gives what it gave before.
    small = dict(iso=0.0, spacing=2.0, voxel_spacing=H, origin=ORIGIN, progress=False)
    before = pm.sample(sphere, **small).points
    interrupt_during(lambda: pm.sample(sphere, iso=0.0, spacing=0.5, voxel_spacing=H, origin=ORIGIN,
                                       tolerance=1e-12, max_iters=3000, progress=False))
    assert np.array_equal(pm.sample(sphere, **small).points, before)


def test_gil_released_during_a_call(sphere):
    # With a switch interval of 1000 s a thread holding the GIL keeps it until
    # it releases it itself. Another thread, woken at the first progress call,
    # can then only run while the call runs if the call released the GIL.
    started, ran = threading.Event(), threading.Event()

    def other():
        if started.wait(120):
            ran.set()

    seen = []

    def cb(label, done, total, detail):
        started.set()
        seen.append(ran.is_set())

    t = threading.Thread(target=other)
    old = sys.getswitchinterval()
    t.start()
    sys.setswitchinterval(1000)
    try:
        pm.sample(sphere, iso=0.0, spacing=1.0, voxel_spacing=H, origin=ORIGIN, progress=cb)
    finally:
        sys.setswitchinterval(old)
        started.set()
        t.join()
    assert len(seen) > 2 and not seen[0]
    assert any(seen), "no other thread ran during the call: the GIL was not released"


def test_tqdm_bars(sphere, capfd, monkeypatch):
    pytest.importorskip("tqdm")
    monkeypatch.delenv("PM_NO_TQDM", raising=False)
    pm.sample(sphere, iso=0.0, spacing=2.0, voxel_spacing=H, origin=ORIGIN)  # progress=None: tqdm when present
    err = capfd.readouterr().err
    assert "particles, dE" in err  # the engine's detail in the bar's postfix


def test_sizing_field_sets_the_spacing(sphere):
    # A constant sizing field h = 1 (on the input's grid) is a uniform
    # spacing of 1: every particle's local spacing is h, and the count is the
    # hexagonal packing's, as with spacing=1.
    h = np.ones_like(sphere, dtype=np.float32)
    r = pm.sample(sphere, iso=0.0, sizing=h, voxel_spacing=H, origin=ORIGIN, progress=False)
    assert np.allclose(r.spacing, 1.0, rtol=1e-6)
    expected = 4 * math.pi * R * R / (math.sqrt(3) / 2)
    assert abs(len(r.points) - expected) < 0.1 * expected
    with pytest.raises(ValueError, match="spacing: give spacing or sizing, not both"):
        pm.sample(sphere, iso=0.0, sizing=h, spacing=1.0, progress=False)
    with pytest.raises(ValueError, match="sizing: expected a 3-D array"):
        pm.sample(sphere, iso=0.0, sizing=h[0], progress=False)
