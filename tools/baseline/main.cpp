// baseline: the meshes we compare against. Marching cubes (OpenVDB) and CGAL
// Mesh_3 on the same isosurface, and CGAL Mesh_3 on a label map
// (pm/cli/baseline_run.h).
#include "pm/cli/baseline_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool("baseline",
                "Baseline meshes to compare particle meshes with, on the same volume "
                "(world units from its header). "
                "mc: marching cubes of F = iso (OpenVDB volumeToMesh, adaptivity 0, "
                "trilinear). cgal: CGAL Mesh_3 "
                "surface mesh of the image isosurface (facet angle 30, facet distance = "
                "size/4, manifold), with the "
                "facet size given or searched so the vertex count matches --vertices. "
                "cgal-labels: CGAL Mesh_3 on a "
                "label map with the lines where three labels meet protected and the "
                "outside label (--outside) not "
                "meshed; writes every interface with face properties label_a < label_b. "
                "Outputs are closed triangle meshes (.ply .obj .off .stl). "
                "With --tets, the cgal modes mesh the volume too (cell radius-edge "
                "ratio, optional cell size), then "
                "run CGAL's sliver perturbation and exudation, and write the labelled "
                "tetrahedra; --vertices then "
                "counts the tetrahedra's vertices.",
                "baseline cgal -i brain_sdf.nrrd --iso 0 --vertices 100000 -o cgal.ply "
                "--stats cgal.json\n"
                "  baseline cgal-labels -i labels.nrrd --vertices 200000 --tets "
                "cgal_volume.mesh --stats cgal.json");
  pm::BaselineRun r;
  pm::add_baseline_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_baseline(r, tool.flags.threads, tool.flags.seed); });
}
