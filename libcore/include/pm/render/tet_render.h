#pragma once
// Pictures of labelled tetrahedral meshes: the outside of the mesh, or a cut
// through it, each face coloured by the material of its tetrahedron (the
// categorical palette of pm/render/render.h, so legends match).
#include "pm/base/mesh.h"
#include "pm/io/tet_mesh.h"
#include "pm/render/render.h"

namespace pm {

/// The triangles render_tets draws, as a surface mesh over all of t's
/// vertices (so the camera is fitted to the whole mesh) with the face int
/// `material`. Without params.clip: the faces of exactly one tetrahedron (the
/// outer boundary; interfaces inside are hidden by it). With params.clip
/// ("x", "y:0.3", ...: the plane of clip_plane, computed with params' camera):
/// a crinkle clip, as ParaView's and 3D Slicer's "clip, keep whole cells":
/// the tetrahedra whose centroid lies on the camera's side of the plane are
/// removed, whole; the boundary faces of the rest are drawn, so the cut is the
/// jagged surface of the cut tetrahedra, each coloured by its own material.
/// Faces are oriented outward from their tetrahedron.
/// \throw InputError when t fails validate(); UsageError for a bad params.clip.
Mesh tet_render_mesh(const LabelledTets& t, const RenderParams& params);

/// Render tet_render_mesh(t, params) in mesh mode, coloured by `material`
/// (params.color_by must be "" or "material"), with params.legend naming
/// each material shown and params.edges drawing the triangle edges.
/// \throw as tet_render_mesh and render(); UsageError when params.mode is
/// disks or splats or color_by names something else.
Image render_tets(const LabelledTets& t, const RenderParams& params);

}  // namespace pm
