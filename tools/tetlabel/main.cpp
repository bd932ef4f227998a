// tetlabel: mesh particles by labelled Delaunay tetrahedra (TetGen): every
// tetrahedron is inside or outside by the field at its circumcentre; the
// faces between inside and outside form the surface. With --conform: the
// conforming tetrahedral mesh of a kept surface plus interior points
// (pm/cli/conform_tets.h).
// (pm/cli/tetlabel_run.h)
#include "pm/cli/run_tool.h"
#include "pm/cli/tetlabel_run.h"

int main(int argc, char** argv) {
  pm::Tool tool("tetlabel",
                "Triangulate surface particles: Delaunay-tetrahedralise them (TetGen), label each tetrahedron "
                "inside (F < iso) or outside by the field at its circumcentre, and write the faces between "
                "inside and outside as a closed, outward-oriented triangle mesh (PLY, VTK .vtp/.vtk, MEDIT, OBJ, OFF, "
                "STL by extension). With --materials (Chapter 6): label each tetrahedron by the material with the "
                "largest indicator at its circumcentre and write the interfaces between materials as one PLY "
                "with integer face properties label_a < label_b (normal from a into b) and pair, plus each "
                "material's closed surface (--material-surfaces), sharing its triangles with its neighbours. "
                "With --conform SURFACE (issue 19): the positional points are INTERIOR points and the "
                "tetrahedra are a constrained Delaunay tetrahedralisation of SURFACE's triangles plus those points, "
                "then TetGen's quality refinement and sliver removal, each step measured (--stats); the boundary and "
                "interfaces of the result are exactly SURFACE's vertices and triangles; each region between them "
                "takes the material the field gives most of its volume (-i/--iso: inside = 1, outside = 0; "
                "--materials: the material labels, SURFACE then carries label_a/label_b per triangle); written to "
                "--tets, no -o. World units throughout.",
                "tetlabel points.ply -i brain_sdf.nrrd --iso 0 -o surface.ply --tets brain.mesh\n"
                "  tetlabel points.ply --materials labels.nrrd -o interfaces.ply --material-surfaces out/ "
                "--tets out/volume.mesh\n"
                "  tetlabel interior.ply --conform surface.ply -i brain_sdf.nrrd --iso 0 --tets volume.vtu "
                "--require min_dihedral>=12 --stats volume_quality.json");
  pm::TetLabelRun r;
  pm::add_tetlabel_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_tetlabel(r, tool.flags, tool.app); });
}
