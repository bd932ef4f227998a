# read_volume: voxels and geometry in libcore's LPS world frame, judged by
# nibabel (an independent NIfTI reader, RAS) and by NRRD headers written here
# by hand; arrays back into the pipelines in either memory order.
import os

import numpy as np
import pytest

import particlemesh as pm

LPS_FROM_RAS = np.diag([-1.0, -1.0, 1.0, 1.0])


def make_nifti(path, data, affine, code=1):
    nib = pytest.importorskip("nibabel")
    img = nib.Nifti1Image(data, affine)
    img.set_sform(affine, code=code)
    img.set_qform(affine, code=code)
    nib.save(img, str(path))


def write_nrrd(path, data, space, directions, origin):
    """A raw little-endian NRRD; data [i, j, k] with axis 0 fastest in the file."""
    dirs = " ".join("(" + ",".join(repr(float(x)) for x in col) + ")" for col in directions)
    header = (f"NRRD0004\ntype: int16\ndimension: 3\nspace: {space}\n"
              f"sizes: {' '.join(str(n) for n in data.shape)}\nspace directions: {dirs}\n"
              f"kinds: domain domain domain\nendian: little\nencoding: raw\n"
              f"space origin: ({','.join(repr(float(x)) for x in origin)})\n\n")
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.asfortranarray(data.astype("<i2")).tobytes(order="F"))


def test_read_nifti_matches_nibabel_in_lps(tmp_path):
    nib = pytest.importorskip("nibabel")
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
    assert vol.frame == "LPS" and vol.source_format == "NIfTI"
    assert vol.source_space.startswith("RAS (sform")
    # nibabel's affine is RAS; libcore's is LPS: x and y negated. NIfTI
    # stores the sform as float32: agreement to float32 rounding.
    atol = 1e-6 * 40
    np.testing.assert_allclose(vol.affine, LPS_FROM_RAS @ ref.affine, rtol=0, atol=atol)
    np.testing.assert_allclose(vol.ras_affine, ref.affine, rtol=0, atol=atol)
    np.testing.assert_allclose(vol.origin, [40.0, -12.5, 7.0], rtol=0, atol=atol)
    np.testing.assert_allclose(vol.spacing, [0.8, 1.2, 2.5], rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(vol.directions, axis=0), 1.0, atol=1e-6)


def test_read_nrrd_space_into_lps(tmp_path):
    data = np.arange(3 * 4 * 5, dtype=np.int16).reshape((3, 4, 5), order="F")
    # Permuted, flipped axes with spacings 0.5, 2, 1.5.
    dirs_ras = np.array([[0, 0.5, 0], [-2, 0, 0], [0, 0, 1.5]]).T  # column a = axis a
    write_nrrd(tmp_path / "ras.nrrd", data, "right-anterior-superior", dirs_ras.T, (10, 20, 30))
    write_nrrd(tmp_path / "lps.nrrd", data, "left-posterior-superior", dirs_ras.T, (10, 20, 30))
    ras = pm.read_volume(tmp_path / "ras.nrrd")
    lps = pm.read_volume(tmp_path / "lps.nrrd")
    for v in (ras, lps):
        assert np.array_equal(v.array, data) and v.array[2, 3, 4] == data[2, 3, 4]
        assert v.frame == "LPS" and v.source_format == "NRRD"
        np.testing.assert_allclose(v.spacing, [0.5, 2.0, 1.5])
    assert ras.source_space == "right-anterior-superior"
    # RAS -> LPS negates x and y of the origin and of every direction.
    np.testing.assert_allclose(ras.origin, [-10, -20, 30])
    np.testing.assert_allclose(ras.directions, np.diag([-1, -1, 1]) @ dirs_ras / [0.5, 2.0, 1.5])
    np.testing.assert_allclose(lps.origin, [10, 20, 30])
    np.testing.assert_allclose(lps.directions, dirs_ras / [0.5, 2.0, 1.5])
    # voxel (i, j, k) at origin + directions @ (spacing * ijk)
    ijk = np.array([2, 3, 4, 1.0])
    # RAS (10 - 2 * 3, 20 + 0.5 * 2, 30 + 1.5 * 4), i.e. LPS (-4, -21, 36)
    np.testing.assert_allclose(ras.affine @ ijk, [-(10 - 2 * 3), -(20 + 0.5 * 2), 30 + 1.5 * 4, 1])


def test_nifti_without_frame_is_voxel_units_and_warns(tmp_path):
    affine = np.diag([2.0, 3.0, 4.0, 1.0])
    affine[:3, 3] = [5, 6, 7]
    make_nifti(tmp_path / "noframe.nii", np.ones((4, 4, 4), np.uint8), affine, code=0)
    with pytest.warns(RuntimeWarning, match="qform_code and sform_code are both 0"):
        vol = pm.read_volume(tmp_path / "noframe.nii")
    assert vol.frame == "none" and vol.frame_note
    np.testing.assert_allclose(vol.origin, [0, 0, 0])
    np.testing.assert_allclose(vol.spacing, [2, 3, 4])


def test_read_shared_nifti_matches_nibabel():
    nib = pytest.importorskip("nibabel")
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
    np.testing.assert_allclose(vol.ras_affine, ref.affine, rtol=0, atol=1e-4 * max(1.0, np.abs(ref.affine).max()))


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
    r = np.linalg.norm(a.points - [0.9, -0.4, 0.2], axis=1)
    assert np.all(np.abs(r - 3.5) < 0.1)
