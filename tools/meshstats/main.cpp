// meshstats: quality report of a triangle mesh (JSON + a short table).
// (pm/cli/meshstats_run.h)
#include "pm/cli/meshstats_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool("meshstats",
                "Quality report of a triangle mesh: radius ratio (2 r_in / r_circ), angles, valence, edge length "
                "over a sizing field h, water-tightness, manifoldness, components, genus, self-intersections "
                "(CGAL), creases (crease_share_20: the share of interior edges whose two faces bend by more than 20 "
                "degrees; per interface and pooled on interface meshes) and distance to the isosurface it "
                "approximates (world units). A table on stderr, JSON "
                "with -o. Exit 3 when a --require check fails. A multi-material interface mesh (face properties "
                "label_a, label_b, from tetlabel --materials) is measured as a whole and per material (each "
                "material's surface taken from the interfaces), plus boundary, junction-curve and bad edges and "
                "faces separating a label from itself (--require keys watertight, manifold, "
                "no_self_intersections, labels_consistent and rr_min/rr_mean then hold for every material). A "
                "tetrahedral mesh (.mesh .vtu .vtk .msh with tetrahedra: tetlabel --tets, meshio, Gmsh, ParaView) "
                "gets the volume report: dihedral angles (min, max, histogram), radius ratio 3 r_in / r_circ, the "
                "shares of tetrahedra under 10 degrees and with every dihedral angle in 25..140 degrees, volume, "
                "per material and overall, and the checks positive, boundary_manifold, triangles_match (--require "
                "also dihedral_min>=D, dihedral_max<=D in degrees, rr_min>=R, rr_mean>=R, share_under_10<=S, "
                "share_25_140>=S).",
                "meshstats surface.ply -i brain_sdf.nrrd --iso 0 --sizing h.nrrd -o quality.json "
                "--require rr_min>=0.3,rr_mean>=0.94,watertight,manifold\n"
                "  meshstats volume.vtu -o volume_quality.json "
                "--require dihedral_min>=12,dihedral_max<=160,share_25_140>=0.99,rr_mean>=0.8,positive");
  pm::MeshStatsRun r;
  pm::add_meshstats_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_meshstats(r, tool.flags); });
}
