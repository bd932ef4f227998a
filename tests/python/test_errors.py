# Bad input: every case raises a Python exception naming the argument or the
# problem, as the tools' error lines do.
import numpy as np
import pytest

import particlemesh as pm
from conftest import sphere_distance, two_material_cube

GOOD = sphere_distance(n=13, h=1.0, radius=3.0, origin=(-6, -6, -6))


@pytest.mark.parametrize("fn", ["sample", "mesh_surface"])
def test_not_3d(fn):
    with pytest.raises(ValueError, match=r"array: expected a 3-D array .* 2-D with shape \(13, 13\)"):
        getattr(pm, fn)(GOOD[0], iso=0.0, spacing=1.0, progress=False)


@pytest.mark.parametrize("dtype", [np.complex128, np.float16, object])
def test_unsupported_dtype(dtype):
    with pytest.raises(ValueError, match="array: unsupported dtype"):
        pm.sample(GOOD.astype(dtype), iso=0.0, spacing=1.0, progress=False)


def test_labels_must_be_integers():
    with pytest.raises(ValueError, match="labels: dtype float64; expected an integer array"):
        pm.mesh_materials(two_material_cube().astype(np.float64), progress=False)


def test_not_contiguous():
    with pytest.raises(ValueError, match=r"array: the array is not contiguous .* numpy.ascontiguousarray\(array\)"):
        pm.sample(GOOD[::2, :, :], iso=0.0, spacing=1.0, progress=False)
    with pytest.raises(ValueError, match="labels: the array is not contiguous"):
        pm.mesh_materials(two_material_cube()[:, ::2, :], progress=False)


@pytest.mark.parametrize("spacing", [0.0, -1.0, (1.0, 0.0, 1.0), (1.0, 1.0, float("nan"))])
def test_non_positive_voxel_spacing(spacing):
    with pytest.raises(ValueError, match="voxel_spacing: .* is not positive"):
        pm.sample(GOOD, iso=0.0, spacing=1.0, voxel_spacing=spacing, progress=False)
    with pytest.raises(ValueError, match="voxel_spacing"):
        pm.mesh_materials(two_material_cube(), voxel_spacing=spacing, progress=False)


def test_bad_parameters_are_value_errors():
    with pytest.raises(ValueError, match="spacing: required"):
        pm.sample(GOOD, iso=0.0, progress=False)
    with pytest.raises(ValueError, match="iso: 50 is outside the value range"):
        pm.sample(GOOD, iso=50.0, spacing=1.0, progress=False)
    with pytest.raises(ValueError, match="kernel"):
        pm.sample(GOOD, iso=0.0, spacing=1.0, kernel="cubic", progress=False)
    with pytest.raises(ValueError, match="grey-level volume .* give iso"):
        pm.mesh_surface(GOOD, progress=False)
    with pytest.raises(ValueError, match="everywhere"):
        pm.mesh_surface(np.zeros((8, 8, 8), np.uint8), progress=False)
    with pytest.raises(ValueError, match="directions: column 0 has length 2"):
        pm.sample(GOOD, iso=0.0, spacing=1.0, directions=np.diag([2.0, 1, 1]), progress=False)
    with pytest.raises(ValueError, match="expected at least 2"):
        pm.mesh_materials(np.ones((8, 8, 8), np.int32), progress=False)
    with pytest.raises(ValueError, match="NaN|finite"):
        bad = GOOD.copy()
        bad[3, 3, 3] = np.nan
        pm.sample(bad, iso=0.0, spacing=1.0, progress=False)


def test_labels_argument_is_named():
    lab = two_material_cube()
    with pytest.raises(ValueError, match=r"labels: expected a 3-D array .* 4-D"):
        pm.mesh_materials(lab[..., None], progress=False)
    with pytest.raises(ValueError, match="labels: unsupported dtype complex128"):
        pm.mesh_materials(lab.astype(np.complex128), progress=False)
    with pytest.raises(ValueError, match="labels: expected a numpy array or a particlemesh.Volume, got list"):
        pm.mesh_materials(lab.tolist(), progress=False)


def test_bad_keywords_are_named():
    with pytest.raises(ValueError, match=r"radius: -1; expected > 0"):
        pm.mesh_surface((GOOD < 0).astype(np.uint8), radius=-1, progress=False)
    with pytest.raises(ValueError, match="upsample: 9; expected 1 to 8"):
        pm.mesh_materials(two_material_cube(), upsample=9, progress=False)
    with pytest.raises(ValueError, match="threads: -2"):
        pm.sample(GOOD, iso=0.0, spacing=1.0, threads=-2, progress=False)
    with pytest.raises(ValueError, match="progress: expected a callable"):
        pm.sample(GOOD, iso=0.0, spacing=1.0, progress="yes")
    with pytest.raises(ValueError, match="init: expected an N x 3 array"):
        pm.sample(GOOD, iso=0.0, spacing=1.0, init=np.zeros((4, 2)), progress=False)
