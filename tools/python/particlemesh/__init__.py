"""particlemesh: particle samples and meshes of volumes, from Python.

The same pipelines as the command-line tools, on numpy arrays:

    import particlemesh as pm
    vol = pm.read_volume("brain.nii.gz")            # array + origin, spacing, directions
    pts = pm.sample(vol, iso=0.5, spacing=2.0)      # Chapter 3: points and normals
    surf = pm.mesh_surface(vol, iso=0.5)            # Chapter 5: make -f Makefile.pipeline surface
    mats = pm.mesh_materials(labels_vol)            # Chapter 6: make -f Makefile.pipeline materials
    surf.to_meshio().write("brain.vtu")

Arrays are indexed [i, j, k] (axis 0 is the volume's first axis, as nibabel's
get_fdata()), C or Fortran contiguous. World coordinates (every point, every
spacing, radius and sizing value) are in the volume's world units: voxel
(i, j, k) sits at origin + directions @ (spacing * (i, j, k)), with the
origin, spacing and directions of a Volume from read_volume, or given as
keywords with a bare array (default: origin 0, spacing 1, identity).

World frame: LPS, as in the tools and libcore (x to the patient's left, y
posterior, z superior; DICOM, ITK, MetaImage, 3D Slicer's files). read_volume
converts every file into it (a NIfTI's RAS sform/qform has x and y negated,
so its origin is -x, -y of nibabel's affine; Volume.ras_affine gives
nibabel's), and every result (points, meshes) is in it. to_meshio(frame="ras")
converts a result to RAS, as the tools' --frame ras does.

Parameters, defaults and units are the tools' (see `particles --help`,
Makefile.pipeline); errors are Python exceptions: bad values or bad data
ValueError, unreadable files OSError. Long calls release the GIL (one call
runs at a time); progress goes to `progress=callable(label, done, total,
detail)`, or to tqdm bars when tqdm is installed (progress=False, or the
environment variable PM_NO_TQDM=1: none);
Ctrl-C raises KeyboardInterrupt and stops the run cleanly.
"""
from __future__ import annotations

import os
import warnings as _warnings
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _core

__all__ = ["Volume", "Samples", "Tetrahedra", "SurfaceMesh", "MaterialMesh", "read_volume", "sample",
           "mesh_surface", "mesh_materials", "__version__"]
__version__ = _core.version


# --- volumes ------------------------------------------------------------------

_LPS_TO_RAS = np.array([-1.0, -1.0, 1.0])


@dataclass
class Volume:
    """A volume: voxel values and where they are in the world.

    array: shape (nx, ny, nz), indexed [i, j, k].
    origin: world position of voxel (0, 0, 0), world units.
    spacing: voxel spacing of each axis, world units.
    directions: 3x3, column a = unit world direction of axis a.
    frame: "LPS" (libcore's world frame: every reader converts into it, as
        `volconv --info` reports), or "none" for a file without a world frame
        (a NIfTI with qform_code = sform_code = 0: voxel index times pixdim;
        INR and VDB files from elsewhere are taken as LPS, see frame_note).
    source_format, source_space: the file's format and the frame it named,
        e.g. "NIfTI", "RAS (sform, scanner_anat, mm)"; "" for arrays.
    frame_note: one line when the coordinates are not anatomical, else "".
    """

    array: np.ndarray
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    spacing: np.ndarray = field(default_factory=lambda: np.ones(3))
    directions: np.ndarray = field(default_factory=lambda: np.eye(3))
    frame: str = "LPS"
    source_format: str = ""
    source_space: str = ""
    frame_note: str = ""

    @property
    def affine(self) -> np.ndarray:
        """4x4 voxel-to-world matrix (LPS): world = affine @ (i, j, k, 1)."""
        a = np.eye(4)
        a[:3, :3] = np.asarray(self.directions) * np.asarray(self.spacing)[None, :]
        a[:3, 3] = self.origin
        return a

    @property
    def ras_affine(self) -> np.ndarray:
        """The same matrix in RAS (x and y negated), as nibabel's img.affine."""
        return np.diag(np.append(_LPS_TO_RAS, 1.0)) @ self.affine


def read_volume(path: Union[str, os.PathLike]) -> Volume:
    """Read a volume file (.nrrd .nhdr .vdb .mha .mhd .nii .nii.gz .inr .inr.gz), as the tools do.

    Geometry in libcore's LPS world frame, mm where the file states units
    (see Volume). Voxel values are returned raw in their stored type (NIfTI
    scl_slope is not applied). Raises OSError for a missing or unreadable
    file, ValueError for a malformed one; the reader's warnings (e.g. a NIfTI
    without a frame) are RuntimeWarnings.
    """
    path = os.fspath(path)
    d = _core.read_volume(path)
    _warn(d["warnings"])
    return Volume(array=d["array"], origin=np.array(d["origin"]), spacing=np.array(d["spacing"]),
                  directions=np.array(d["directions"]), frame=d["frame"], source_format=d["source_format"],
                  source_space=d["source_space"], frame_note=d["frame_note"])


def _grid(volume, origin, voxel_spacing, directions, arg):
    """(array, origin, spacing, directions): a Volume's geometry unless given."""
    if isinstance(volume, Volume):
        return (volume.array, volume.origin if origin is None else origin,
                volume.spacing if voxel_spacing is None else voxel_spacing,
                volume.directions if directions is None else directions)
    if not isinstance(volume, np.ndarray):
        raise ValueError(f"{arg}: expected a numpy array or a particlemesh.Volume, got {type(volume).__name__}")
    return volume, origin, voxel_spacing, directions


# --- progress -----------------------------------------------------------------

class _TqdmProgress:
    """One tqdm bar per loop label (stages of a pipeline, particle levels)."""

    def __init__(self, tqdm):
        self._tqdm = tqdm
        self._bars = {}

    def __call__(self, label, done, total, detail):
        bar = self._bars.get(label)
        if bar is None:
            bar = self._bars[label] = self._tqdm(total=total, desc=label, leave=False)
        bar.n = min(done, total) if total else done
        bar.set_postfix_str(detail, refresh=False)
        bar.refresh()

    def close(self):
        for bar in self._bars.values():
            bar.close()
        self._bars.clear()


def _progress(progress):
    if progress is False or progress is None and os.environ.get("PM_NO_TQDM"):
        return None, None
    if callable(progress):
        return progress, None
    if progress is None or progress is True:
        try:
            from tqdm.auto import tqdm
        except ImportError:
            if progress is True:
                raise ValueError("progress=True needs tqdm (Debian: python3-tqdm); or pass a callable") from None
            return None, None
        bar = _TqdmProgress(tqdm)
        return bar, bar
    raise ValueError(f"progress: expected a callable, True, False or None, got {type(progress).__name__}")


def _run(fn, progress, *args):
    cb, bar = _progress(progress)
    try:
        return fn(*args, cb)
    finally:
        if bar is not None:
            bar.close()


def _warn(ws):
    for w in ws:
        _warnings.warn(w, RuntimeWarning, stacklevel=3)


# --- results ------------------------------------------------------------------

def _meshio():
    try:
        import meshio
    except ImportError:
        raise ImportError("to_meshio() needs meshio (Debian: python3-meshio)") from None
    return meshio


def _in_frame(vectors, frame):
    """N x 3 points or normals (LPS) in `frame`: "lps" as they are, "ras" with x and y negated."""
    f = str(frame).lower()
    if f == "lps":
        return vectors
    if f == "ras":
        return None if vectors is None else np.asarray(vectors) * _LPS_TO_RAS
    raise ValueError(f'frame: "{frame}" is unknown; expected lps or ras')


@dataclass
class Samples:
    """Particles on an isosurface: N x 3 points and unit normals (outward, grad F),
    local spacing (world units), energy and curvedness (1/world units)."""

    points: np.ndarray
    normals: np.ndarray
    spacing: np.ndarray
    energy: np.ndarray
    curvature: np.ndarray
    converged: bool = True
    iterations: int = 0

    def to_meshio(self, frame: str = "lps"):
        """The points as a meshio.Mesh of vertex cells with normals and scalars
        (frame "lps", or "ras": x and y negated, as the tools' --frame)."""
        meshio = _meshio()
        n = len(self.points)
        return meshio.Mesh(_in_frame(self.points, frame), [("vertex", np.arange(n).reshape(-1, 1))],
                           point_data={"normals": _in_frame(self.normals, frame), "spacing": self.spacing,
                                       "energy": self.energy, "curvature": self.curvature})


@dataclass
class Tetrahedra:
    """Labelled Delaunay tetrahedra (what tetlabel --tets writes): points N x 3
    (world units, LPS), tets T x 4 (indices into points), labels T (1 inside
    for mesh_surface; the material label for mesh_materials; the outside is
    left out)."""

    points: np.ndarray
    tets: np.ndarray
    labels: np.ndarray

    def to_meshio(self, frame: str = "lps"):
        """A meshio.Mesh of "tetra" cells with the cell data "material" (as the tools' .vtu)."""
        meshio = _meshio()
        return meshio.Mesh(_in_frame(self.points, frame), [("tetra", self.tets)],
                           cell_data={"material": [self.labels]})


@dataclass
class SurfaceMesh:
    """mesh_surface's result: a closed, outward-oriented triangle mesh.

    points V x 3 (world units, LPS), triangles F x 3 (counter-clockwise seen
    from outside), normals V x 3 (the particles'), pairs F x 2 = (1, 0): the
    inside and outside label of every triangle, the normal pointing from the
    first into the second (as in MaterialMesh). tetrahedra: the labelled
    Delaunay tetrahedra when asked (tetrahedra=True), else None.
    """

    points: np.ndarray
    triangles: np.ndarray
    normals: Optional[np.ndarray]
    pairs: np.ndarray
    particles: Samples
    tetrahedra: Optional[Tetrahedra] = None
    kind: str = "mask"
    warnings: List[str] = field(default_factory=list)
    seconds: Dict[str, float] = field(default_factory=dict)

    def to_meshio(self, frame: str = "lps"):
        """A meshio.Mesh of the triangles, cell data label_a/label_b, point data normals
        (frame "lps", or "ras": x and y negated, as the tools' --frame)."""
        meshio = _meshio()
        pd = {} if self.normals is None else {"normals": _in_frame(self.normals, frame)}
        return meshio.Mesh(_in_frame(self.points, frame), [("triangle", self.triangles)], point_data=pd,
                           cell_data={"label_a": [self.pairs[:, 0]], "label_b": [self.pairs[:, 1]]})


@dataclass
class MaterialMesh:
    """mesh_materials' result: the interfaces between materials.

    points V x 3 (world units, LPS), triangles F x 3, pairs F x 2 = (label_a, label_b) with
    label_a < label_b and the normal pointing from label_a into label_b;
    label_pairs: the distinct pairs; surfaces: label -> (points, triangles) of
    each material's closed surface (outward); outside_label: the material
    outside the volume (the background); tetrahedra: the Delaunay
    tetrahedra labelled by material (outside left out) when asked
    (tetrahedra=True), else None.
    """

    points: np.ndarray
    triangles: np.ndarray
    pairs: np.ndarray
    label_pairs: List[Tuple[int, int]]
    surfaces: Dict[int, Tuple[np.ndarray, np.ndarray]]
    outside_label: int
    particles: Dict[str, np.ndarray]
    tetrahedra: Optional[Tetrahedra] = None
    warnings: List[str] = field(default_factory=list)
    seconds: Dict[str, float] = field(default_factory=dict)

    def to_meshio(self, frame: str = "lps"):
        """A meshio.Mesh of the interface triangles, cell data label_a/label_b
        (frame "lps", or "ras": x and y negated, as the tools' --frame)."""
        meshio = _meshio()
        return meshio.Mesh(_in_frame(self.points, frame), [("triangle", self.triangles)],
                           cell_data={"label_a": [self.pairs[:, 0]], "label_b": [self.pairs[:, 1]]})


def _samples(d) -> Samples:
    return Samples(points=d["points"], normals=d["normals"], spacing=d["spacing"], energy=d["energy"],
                   curvature=d["curvature"], converged=d.get("converged", True), iterations=d.get("iterations", 0))


def _particles_of(d) -> Samples:
    pd = d["point_data"]
    return Samples(points=d["points"], normals=d["normals"], spacing=pd["spacing"], energy=pd["energy"],
                   curvature=pd["curvature"])


def _tets(d) -> Optional[Tetrahedra]:
    if d is None:
        return None
    return Tetrahedra(points=d["points"], tets=d["tets"], labels=d["labels"])


# --- the functions ------------------------------------------------------------

def sample(volume, *, iso: float = 0.0, spacing: Optional[float] = None, density: float = 0.0,
           alpha_cap: float = 10.0, sizing=None, init=None, init_count: int = 500,
           lattice_init: Optional[bool] = None, count: int = 0, kernel: str = "bspline",
           energy: str = "cotangent", tolerance: float = 0.0015, population_tolerance: float = 0.001,
           population: bool = True, max_iters: int = 2000, coarse_to_fine: Optional[bool] = None,
           coarse_start: float = 0.0, thin_seeds: float = 0.0, settle: float = 0.0, seed: int = 1,
           threads: int = 0, origin=None, voxel_spacing=None,
           directions=None, progress=None) -> Samples:
    """Particles on the isosurface F = iso of a volume (the `particles` tool, Chapter 3).

    volume: a Volume or a 3-D array (grey values or a distance field; float or
    integer). spacing: particle spacing on flat parts, world units (required
    unless sizing); density: particles per radian of curvature (0 = uniform);
    sizing: a sizing-field Volume or array (world units, on its own grid;
    an array takes the input's geometry); init: N x 3 seed points. The other
    keywords are the tool's options of the same name (lattice_init and
    coarse_to_fine default to on, as for volumes). Returns Samples.
    """
    arr, o, s, d = _grid(volume, origin, voxel_spacing, directions, "array")
    so = ss = sd = None
    if sizing is not None:
        if isinstance(sizing, Volume):
            sizing, so, ss, sd = sizing.array, sizing.origin, sizing.spacing, sizing.directions
        else:
            so, ss, sd = o, s, d
            if not isinstance(sizing, np.ndarray):
                raise ValueError(f"sizing: expected a numpy array or a particlemesh.Volume, got {type(sizing).__name__}")
    if init is not None:
        init = np.asarray(init, dtype=float)
    r = _run(_core.sample, progress, arr, o, s, d, float(iso), spacing, float(density), float(alpha_cap), sizing,
             so, ss, sd, init, int(init_count), lattice_init, int(count), kernel, energy, float(tolerance),
             float(population_tolerance), bool(population), int(max_iters), coarse_to_fine, float(coarse_start),
             float(thin_seeds), float(settle), int(seed), int(threads))
    out = _samples(r)
    ws = list(r["warnings"])
    if not out.converged:
        ws.append(f"particles: not converged after {out.iterations} iterations (max_iters {max_iters} per level)")
    _warn(ws)
    return out


def mesh_surface(volume, *, iso: Optional[float] = None, labels: Optional[Sequence[int]] = None,
                 stencil: str = "ball", min_component: int = 0, radius: Optional[float] = None,
                 upsample: Optional[int] = None, eps: float = 0.5, delta: float = 0.05, spacing: Optional[float] = None,
                 hmin: Optional[float] = None, morph: bool = False, tighten: bool = False, decimate: int = 4,
                 tolerance: float = 1e-4, improve: int = 3, tetrahedra: bool = False, seed: int = 1,
                 threads: int = 0, origin=None,
                 voxel_spacing=None, directions=None, progress=None) -> SurfaceMesh:
    """The Chapter 5 pipeline (`make -f Makefile.pipeline surface`) on a volume.

    A mask (an integer array with exactly two values, or `labels` of a label
    map) goes mask -> morphology (close, open with `stencil`) -> tighten
    (`radius`, world units, and `upsample`; None = auto as `tighten`: the
    largest voxel spacing, upsampled when an axis has < 8 voxels) -> signed distance; a
    grey-level volume needs `iso` and is meshed directly (morph/tighten=True:
    through the mask stages). Then medial axis -> sizing field (eps, hmin
    default half the smallest spacing) -> gradient limit (delta) -> marching
    cubes seeds (decimate) -> particles (tolerance; or a uniform `spacing`)
    -> labelled Delaunay tetrahedra -> `improve` rounds. Keywords are the
    Makefile's variables in lower case, same defaults and units (world
    units, LPS); tetrahedra=True also returns the inside tetrahedra (the
    Makefile's volume.mesh).
    """
    arr, o, s, d = _grid(volume, origin, voxel_spacing, directions, "array")
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8)
    labels = [] if labels is None else [int(x) for x in labels]
    r = _run(_core.mesh_surface, progress, arr, o, s, d, None if iso is None else float(iso), labels, stencil,
             int(min_component), radius, upsample, float(eps), float(delta), spacing, hmin, bool(morph),
             bool(tighten), int(decimate), float(tolerance), int(improve), bool(tetrahedra), int(seed), int(threads))
    nf = len(r["triangles"])
    pairs = np.tile(np.array([[1, 0]], dtype=np.int64), (nf, 1))
    out = SurfaceMesh(points=r["points"], triangles=r["triangles"], normals=r.get("normals"), pairs=pairs,
                      particles=_particles_of(r["particles"]), tetrahedra=_tets(r.get("tetrahedra")), kind=r["kind"],
                      warnings=list(r["warnings"]), seconds=dict(r["seconds"]))
    _warn(out.warnings)
    return out


def mesh_materials(labels, *, merge: Optional[str] = None, min_voxels: int = 0, pad: Union[str, int] = "auto",
                   pad_value: Optional[Union[str, int]] = None, morph_ops: str = "close:ball,open:ball",
                   downsample: int = 1, radius: Optional[float] = None, upsample: Optional[int] = None,
                   eps: float = 0.3, delta: float = 0.05,
                   hmin: Optional[float] = None, ma_side: str = "inside", spacing: Optional[float] = None,
                   decimate: int = 1, improve: int = 3, tetrahedra: bool = False, seed: int = 1, threads: int = 0,
                   origin=None, voxel_spacing=None, directions=None, progress=None) -> MaterialMesh:
    """The Chapter 6 pipeline (`make -f Makefile.pipeline materials`) on a label map.

    labels: a Volume or 3-D integer array; every label is a material (0
    included). merge ("1,2:1 3-5:2"), min_voxels, pad/pad_value -> morphology
    per label (morph_ops, or "none"; downsample) with voting fill -> tighten
    per label (radius, world units, and upsample; None = auto, from the label
    map after morphology: its largest voxel spacing) -> medial axes (ma_side:
    "inside", each material's inner axis, whose union is every interface's
    medial axis; "both" adds the outer ones, slower; "outside") -> sizing
    field (eps, hmin default half the radius used) -> gradient limit (delta) -> junction seeds
    (decimate) -> multi-material particles (or a uniform `spacing`) ->
    labelled Delaunay tetrahedra -> `improve` rounds on the interfaces.
    Keywords are Makefile.ch6's variables in lower case, same defaults
    (world units, LPS); tetrahedra=True also returns the tetrahedra labelled
    by material (the Makefile's volume.mesh).
    """
    arr, o, s, d = _grid(labels, origin, voxel_spacing, directions, "labels")
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8)
    if isinstance(pad, str) and pad != "auto":
        raise ValueError(f'pad: "{pad}"; expected a voxel count or "auto"')
    pad_n = -1 if isinstance(pad, str) else int(pad)
    if pad_n < -1 or (not isinstance(pad, str) and pad_n < 0):
        raise ValueError(f"pad: {pad}; expected >= 0 voxels or \"auto\"")
    r = _run(_core.mesh_materials, progress, arr, o, s, d, merge or "", int(min_voxels), pad_n,
             "" if pad_value is None else str(pad_value),
             morph_ops, int(downsample), radius, upsample, float(eps), float(delta), hmin, str(ma_side), spacing,
             int(decimate), int(improve), bool(tetrahedra), int(seed), int(threads))
    cd = r["cell_data"]
    pairs = np.stack([cd["label_a"], cd["label_b"]], axis=1) if len(r["triangles"]) else np.zeros((0, 2), np.int64)
    surfaces = {int(l): (m["points"], m["triangles"]) for l, m in r["surfaces"].items()}
    p = r["particles"]
    particles = dict(p["point_data"])
    particles["points"] = p["points"]
    particles["normals"] = p["normals"]
    out = MaterialMesh(points=r["points"], triangles=r["triangles"], pairs=pairs,
                       label_pairs=[tuple(x) for x in r["label_pairs"]], surfaces=surfaces,
                       outside_label=int(r["outside_label"]), particles=particles,
                       tetrahedra=_tets(r.get("tetrahedra")), warnings=list(r["warnings"]),
                       seconds=dict(r["seconds"]))
    _warn(out.warnings)
    return out
