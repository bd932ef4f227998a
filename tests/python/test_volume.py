# read_volume against nibabel (an independent NIfTI reader), and arrays back
# into the pipelines in either memory order.
import os

import numpy as np
import pytest

import particlemesh as pm

nib = pytest.importorskip("nibabel")


def make_nifti(path, data, affine):
    img = nib.Nifti1Image(data, affine)
    img.set_sform(affine, code=1)
    img.set_qform(affine, code=1)
    nib.save(img, str(path))


def test_read_volume_matches_nibabel(tmp_path):
    rng = np.random.default_rng(5)
    data = rng.integers(-300, 3000, size=(5, 6, 7)).astype(np.int16)
    # A rotation about z by 30 degrees, anisotropic spacing, an offset.
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    affine = np.eye(4)
    affine[:3, :3] = rot @ np.diag([0.8, 1.2, 2.5])
    affine[:3, 3] = [-40.0, 12.5, 7.0]
    path = tmp_path / "rotated.nii.gz"
    make_nifti(path, data, affine)

    ref = nib.load(str(path))
    vol = pm.read_volume(path)
    assert vol.array.dtype == np.int16
    assert vol.array.shape == (5, 6, 7)
    assert np.array_equal(vol.array, np.asanyarray(ref.dataobj))
    assert vol.array[4, 5, 6] == data[4, 5, 6]
    assert vol.frame == "RAS"
    # NIfTI stores the sform as float32: agreement to float32 rounding.
    np.testing.assert_allclose(vol.affine, ref.affine, rtol=0, atol=1e-5 * 40)
    np.testing.assert_allclose(vol.spacing, [0.8, 1.2, 2.5], rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(vol.directions, axis=0), 1.0, atol=1e-6)


def test_read_shared_nifti_matches_nibabel():
    root = os.path.join(os.environ.get("PM_SOURCE_DIR", "."), "..", "shared", "data")
    found = []
    for d, _, files in os.walk(root):
        found += [os.path.join(d, f) for f in files if f.endswith((".nii", ".nii.gz"))]
    if not found:
        pytest.skip("no NIfTI in ../shared/data")
    path = sorted(found, key=os.path.getsize)[0]
    ref = nib.load(path)
    vol = pm.read_volume(path)
    assert vol.array.shape == ref.shape[:3]
    assert np.array_equal(vol.array, np.asanyarray(ref.dataobj).reshape(vol.array.shape))
    np.testing.assert_allclose(vol.affine, ref.affine, rtol=0, atol=1e-4 * max(1.0, np.abs(ref.affine).max()))


def test_missing_file_is_oserror(tmp_path):
    with pytest.raises(OSError, match="nothere.nrrd"):
        pm.read_volume(tmp_path / "nothere.nrrd")


def test_c_and_fortran_order_give_the_same_samples():
    from conftest import sphere_distance
    # off-centre, so that a transposed array would give other points
    d = sphere_distance(n=21, h=0.6, radius=3.5, origin=(-6, -6, -6), centre=(0.9, -0.4, 0.2))
    kw = dict(iso=0.0, spacing=1.2, voxel_spacing=0.6, origin=(-6, -6, -6), progress=False)
    a = pm.sample(np.ascontiguousarray(d), **kw)
    b = pm.sample(np.asfortranarray(d), **kw)
    assert np.array_equal(a.points, b.points)
