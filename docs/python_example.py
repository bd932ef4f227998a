#!/usr/bin/env python3
"""particlemesh from Python: a notebook-style walk through the three calls.

Run it as a script (the tests do) or paste the cells into Jupyter:
    PYTHONPATH=build/python /usr/bin/python3 docs/python_example.py [OUTDIR]
"""
# %% Setup: the module, and where to write the meshes.
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
# (pm.read_volume("scan.nii.gz") gives the same kind of object from a file.)

# %% Chapter 3: particles on the isosurface F = 0, 1 mm apart.
pts = pm.sample(sphere, iso=0.0, spacing=1.0, progress=False)
r = np.linalg.norm(pts.points, axis=1)
print(f"particles: {len(pts.points)} points, radius {r.mean():.3f} +- {r.std():.3f} mm")

# %% Chapter 5: the whole single-surface pipeline (sizing field, particles, Delaunay, improvement).
surf = pm.mesh_surface(sphere, iso=0.0, progress=False)
print(f"sphere: {len(surf.points)} vertices, {len(surf.triangles)} triangles, stages {sorted(surf.seconds)}")
surf.to_meshio().write(f"{out}/sphere.vtu")

# %% Chapter 6: a label map of two materials in a box (0 = background).
labels = np.zeros((20, 20, 20), dtype=np.int32)
labels[4:16, 4:16, 4:16] = 1
labels[10:16, 4:16, 4:16] = 2
mats = pm.mesh_materials(labels, voxel_spacing=0.5, radius=0.5, progress=False)
print(f"interfaces: {len(mats.triangles)} triangles between the pairs {mats.label_pairs}")
mats.to_meshio().write(f"{out}/interfaces.vtu")
print(f"wrote {out}/sphere.vtu and {out}/interfaces.vtu")
