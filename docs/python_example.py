#!/usr/bin/env python3
"""particlemesh from Python: a notebook-style walk through the calls.

Run it as a script (the tests do) or paste the cells (# %%) into Jupyter:
    PYTHONPATH=build/python /usr/bin/python3 docs/python_example.py [OUTDIR]
World units are mm here; every coordinate is in libcore's LPS frame.
"""
# %% Setup: the module, and where to write the meshes.
import os
import sys
import tempfile

import numpy as np

import particlemesh as pm

out = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="pm_example_")

# %% A volume: the signed distance to a sphere of radius 4 mm on a 0.5 mm grid.
# Arrays are indexed [i, j, k]; voxel (i, j, k) sits at origin + spacing * (i, j, k).
h, origin = 0.5, np.array([-6.0, -6.0, -6.0])
ax = origin[0] + h * np.arange(25)
x, y, z = np.meshgrid(ax, ax, ax, indexing="ij")
sphere = pm.Volume(array=np.sqrt(x * x + y * y + z * z) - 4.0, origin=origin, spacing=np.full(3, h))

# %% Chapter 3: particles on the isosurface F = 0, 1 mm apart.
pts = pm.sample(sphere, iso=0.0, spacing=1.0, progress=False)
r = np.linalg.norm(pts.points, axis=1)
print(f"particles: {len(pts.points)} points, radius {r.mean():.3f} +- {r.std():.3f} mm")

# %% Chapter 5: the whole single-surface pipeline (sizing field, particles, Delaunay,
# improvement), as `make -f Makefile.pipeline surface`; with the tetrahedra inside.
surf = pm.mesh_surface(sphere, iso=0.0, tetrahedra=True, progress=False)
print(f"sphere: {len(surf.points)} vertices, {len(surf.triangles)} triangles, "
      f"{len(surf.tetrahedra.tets)} tetrahedra; stages {sorted(surf.seconds)}")
surf.to_meshio().write(os.path.join(out, "sphere.vtu"))
surf.tetrahedra.to_meshio().write(os.path.join(out, "sphere_tets.vtu"))

# %% Chapter 6: a label map of two materials in a box (0 = background), 0.5 mm voxels.
labels = np.zeros((20, 20, 20), dtype=np.int32)
labels[4:16, 4:16, 4:16] = 1
labels[10:16, 4:16, 4:16] = 2
mats = pm.mesh_materials(labels, voxel_spacing=0.5, progress=False)
print(f"interfaces: {len(mats.triangles)} triangles between the pairs {mats.label_pairs}")
mats.to_meshio().write(os.path.join(out, "interfaces.vtu"))

# %% Files: the same label map as a NIfTI (RAS, as nibabel writes it), read back in LPS.
try:
    import nibabel as nib
except ImportError:
    nib = None
if nib is not None:
    affine = np.diag([0.5, 0.5, 0.5, 1.0])
    affine[:3, 3] = [10.0, 20.0, 30.0]
    img = nib.Nifti1Image(labels, affine)
    img.set_sform(affine, code=1)
    nib.save(img, os.path.join(out, "labels.nii.gz"))
    vol = pm.read_volume(os.path.join(out, "labels.nii.gz"))
    print(f"read: {vol.array.shape} {vol.array.dtype}, frame {vol.frame} from {vol.source_space}; "
          f"origin {vol.origin} (nibabel, RAS: {vol.ras_affine[:3, 3]})")
print(f"wrote {out}/sphere.vtu, sphere_tets.vtu and interfaces.vtu")
