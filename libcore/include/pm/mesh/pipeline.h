#pragma once
// The Chapter 5 and Chapter 6 pipelines as library calls, chaining the same
// library functions with the same defaults as Makefile.pipeline (surface) and
// Makefile.ch6 (materials) chain the tools, for front ends that hold the volume in
// memory (the Python module). Point sets pass between stages rounded to
// float32, as the PLY files between the tools do, so that a pipeline gives
// the Makefile's result. Also the tetlabel tool's two meshing stages
// (particles -> surface, particles -> interfaces), which the tool calls.
// World units throughout (from the volume's geometry).
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "pm/base/volume.h"
#include "pm/field/field.h"
#include "pm/field/materials.h"
#include "pm/base/mesh.h"
#include "pm/mesh/topology.h"
#include "pm/mesh/surface_improve.h"
#include "pm/mesh/tetlabel.h"
#include "pm/mesh/tetlabel_materials.h"

namespace pm {

// --- the tetlabel stage ------------------------------------------------------

/// Drop points closer than `tol` (world units) to an earlier point; normals
/// and vertex scalars follow. TetGen refuses duplicates (e.g. two seeds that
/// converged onto one quadruple point). Returns the number dropped.
std::size_t drop_duplicate_points(Mesh& points, double tol);

enum class InsideSide { automatic, below, above };

struct SurfaceMeshParams {
  InsideSide inside = InsideSide::automatic;  ///< which side of F = iso is the material
  bool repair = true;                         ///< pm::make_manifold before extracting the surface
  int improve = 0;                            ///< rounds of pm::improve_surface (0 = the Delaunay surface)
};

struct SurfaceMeshResult {
  /// Closed, outward-oriented surface; vertex scalar "index" = particle index;
  /// normals = the particles' normals when they have some.
  Mesh surface;
  TetMesh tets;  ///< enclosed Delaunay tetrahedra, label 1 inside, 0 outside (unimproved)
  TetLabelStats label_stats;
  bool below = true;            ///< the material is F < iso
  std::size_t relabelled = 0;   ///< tetrahedra changed by the manifold repair
  MeshTopology topology;        ///< of the Delaunay surface (before improvement)
  std::size_t buried = 0;       ///< particles on no surface triangle
  std::optional<SurfaceImproveStats> improve;  ///< when improvement ran
  /// People-facing warnings (not closed, particles buried, improvement skipped).
  std::vector<std::string> warnings;
};

/// Single-material meshing (SPEC §5): enclosed Delaunay tetrahedralisation of
/// the particles, each tetrahedron inside when F at its circumcentre is on
/// the material's side of iso (outside the field's domain: outside), manifold
/// repair, the surface between inside and outside, then p.improve rounds of
/// improvement when that surface is a closed manifold (else a warning).
/// `what` names the points in messages.
/// \throw InputError for fewer than 4 points, TetGen failures, no inside
/// tetrahedron; UsageError for improve > 0 without repair.
SurfaceMeshResult mesh_surface_from_particles(const Mesh& points, const ScalarField& field, double iso,
                                              const SurfaceMeshParams& p = {}, const std::string& what = "points");

struct MaterialStageParams {
  std::optional<int> outside_label;  ///< empty = pm::auto_outside_label
  bool repair = true;
  int improve = 0;                   ///< rounds of pm::improve_interfaces
};

struct MaterialStageResult {
  /// Interfaces and material surfaces; vertex scalars of the particles
  /// (junction, label_a, ...) copied onto every mesh.
  MaterialMeshes meshes;
  TetMesh tets;                 ///< Delaunay tetrahedra labelled by material
  int outside_label = 0;
  std::size_t duplicates = 0;   ///< particles dropped as duplicates
  std::size_t particles = 0;    ///< particles meshed (after dropping duplicates)
  std::size_t buried = 0;       ///< particles on no interface
  MeshTopology interface_topology;  ///< of the Delaunay interfaces
  std::optional<SurfaceImproveStats> improve;
  std::vector<std::string> warnings;
};

/// Multi-material meshing (SPEC §6.4.3): duplicates dropped (within 1e-7 of
/// the bounding-box diagonal), Delaunay, pm::mesh_materials, then
/// p.improve rounds on the interfaces (the material surfaces rebuilt from
/// them). \throw InputError for fewer than 4 points, TetGen failures, a single
/// material everywhere; UsageError for improve > 0 without repair.
MaterialStageResult mesh_materials_from_particles(Mesh points, const MaterialSet& ms,
                                                  const MaterialStageParams& p = {},
                                                  const std::string& what = "points");

// --- Chapter 5: one surface ----------------------------------------------------

/// Makefile.pipeline surface's variables, same names and defaults.
struct SurfacePipelineParams {
  /// ISO: isovalue of a grey-level volume (required unless the volume is a
  /// mask, i.e. has exactly two values, or `labels` is given).
  std::optional<double> iso;
  std::vector<std::int64_t> labels;  ///< LABELS: mesh the mask of these labels
  std::string stencil = "ball";      ///< STENCIL of the close/open morphology
  std::size_t min_component = 0;     ///< MIN_COMPONENT, voxels (0 = keep all)
  double radius = 0;                 ///< R: tightening radius, world units (0 = auto, pm::tighten_defaults)
  int upsample = 0;                  ///< UPSAMPLE of the tightening (0 = auto, pm::tighten_defaults)
  double eps = 0.5;                  ///< EPS of the sizing field
  double delta = 0.05;               ///< DELTA: gradient limit of the sizing field
  double spacing = 0;                ///< SPACING: uniform particle spacing, world units (0 = the sizing field)
  double hmin = 0;                   ///< HMIN, world units (0 = half the smallest voxel spacing)
  bool morph = false;                ///< MORPH=1: mask stages on a thresholded grey volume
  bool tighten = false;              ///< TIGHTEN=1: the same
  int decimate = 4;                  ///< DECIMATE of the marching-cubes seeds
  double tolerance = 1e-4;           ///< PTOL: particle convergence tolerance
  int improve = 3;                   ///< IMPROVE: rounds of surface improvement
  std::uint64_t seed = 1;            ///< --seed of the particles
  bool progress = true;              ///< pm::Progress per stage and in the particle loops
};

struct SurfacePipelineResult {
  std::string kind;   ///< "mask" or "grey": the branch taken
  Mesh particles;     ///< points.ply: positions, normals, energy, spacing, curvature
  Mesh surface;       ///< surface.ply
  TetMesh tets;       ///< volume.mesh: label 1 inside
  Volume field;       ///< the field meshed (the input, or the tightened signed distance)
  double field_iso = 0;
  std::vector<std::string> warnings;
  std::map<std::string, double> seconds;  ///< per stage
};

/// The Chapter 5 pipeline on a volume in memory (`what` names it in messages).
/// \throw UsageError for a grey-level volume without iso, bad parameters (as
/// the tools); InputError for a volume with one value everywhere, an iso
/// outside the value range, or whatever a stage throws.
SurfacePipelineResult mesh_surface_pipeline(const Volume& input, const SurfacePipelineParams& p = {},
                                            const std::string& what = "volume");

// --- Chapter 6: many materials -------------------------------------------------

/// Makefile.ch6's variables, same names and defaults (label map input).
struct MaterialsPipelineParams {
  std::string merge;                 ///< MERGE, e.g. "1,2:1 3-5:2" ("" = none)
  std::size_t min_voxels = 0;        ///< MIN_VOXELS
  long pad = -1;                     ///< PAD voxels (-1 = auto: 3 x downsample when the border holds
                                     ///< more than one label, pm::border_padding)
  std::string pad_value;             ///< PAD_VALUE: "new", "auto" or a label ("" = auto with pad -1, else new)
  std::string morph_ops = "close:ball,open:ball";  ///< MORPH_OPS ("none" = no morphology)
  int downsample = 1;                ///< DOWNSAMPLE
  double radius = 0;                 ///< R: tightening radius, world units (0 = auto, pm::tighten_defaults
                                     ///< of the label map after morphology and downsampling)
  int upsample = 0;                  ///< UPSAMPLE (0 = auto)
  double eps = 0.3;                  ///< EPS
  double delta = 0.05;               ///< DELTA
  double hmin = -1;                  ///< HMIN, world units (< 0 = half the radius tighten used; the
                                     ///< radius on a tiny, upsampled volume)
  double spacing = 0;                ///< SPACING: uniform spacing (0 = the sizing field)
  std::string ma_side = "inside";    ///< MA_SIDE: "inside" (each material's inner medial axis), "outside" or "both"
  int decimate = 1;                  ///< DECIMATE of the junction seeds
  int improve = 3;                   ///< IMPROVE
  std::uint64_t seed = 1;
  bool progress = true;
};

struct MaterialsPipelineResult {
  Mesh particles;                    ///< points.ply (junction, label_a..label_d, ...)
  MaterialStageResult meshes;        ///< interfaces.ply, material_<L>.ply, volume.mesh
  Volume labels;                     ///< morph.nrrd: the label map after grouping and morphology
  std::vector<std::string> warnings;
  std::map<std::string, double> seconds;
};

/// The Chapter 6 pipeline on a label map in memory (integer labels).
/// \throw UsageError / InputError as the tools.
MaterialsPipelineResult mesh_materials_pipeline(const Volume& labels, const MaterialsPipelineParams& p = {},
                                                const std::string& what = "labels");

}  // namespace pm
