// render: draw a point set or mesh to a PNG (oriented disks, surface splats or
// shaded triangles) for looking at results (pm/cli/render_run.h).
#include "pm/cli/render_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool("render",
                "Render a point set or mesh (.ply .vtk .mesh .off .obj .stl) to a PNG with an orthographic camera "
                "fitted to its bounding box. Points are drawn as oriented disks or blended surface splats in their "
                "tangent planes (normals from nx ny nz, else from faces); meshes as shaded triangles. A tetrahedral "
                "mesh (.mesh .vtu .vtk .msh with tetrahedra) is drawn as its outer boundary coloured by material, "
                "or with --clip as a cut: the tetrahedra on the camera's side of the plane are removed whole "
                "(a crinkle clip, as ParaView's 'keep whole cells') and the faces of the rest coloured by material.",
                "render particles.ply -o view.png --azimuth 45 --elevation 30 --size 1024x768 --color-by curvature\n"
                "  render interfaces.ply -o cut.png --color-by pair --legend --clip x   # inner materials\n"
                "  render volume.vtu -o cut.png --clip y:0.5 --legend --edges   # tetrahedra cut at mid-y");
  pm::RenderRun r;
  pm::add_render_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_render(r); });
}
