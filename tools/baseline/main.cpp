// baseline: the meshes we compare against. Marching cubes (OpenVDB) and CGAL
// Mesh_3 on the same isosurface, and CGAL Mesh_3 on a label map.
#include <cmath>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/field_options.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/io/volume_io.h"
#include "pm/baseline/baseline.h"
#include "pm/mesh/tetlabel.h"
#include "pm/cli/frame_option.h"
#include "pm/io/output_path.h"

namespace {

// Mesh with CGAL at a given size, or search the size that gives `target`
// vertices (within `tol`): N ~ 1/size^2, so size *= sqrt(N / target).
template <class Run>
pm::CgalMeshResult sized_run(const Run& run, pm::CgalMeshParams p, std::size_t target, double start_size,
                             double tol, int max_runs, pm::Json& st) {
  if (target == 0) return run(p);
  p.facet_size = start_size;  // a given --distance stays fixed; by default it is size / 4 at every size
  pm::CgalMeshResult best;
  double best_err = 1e300;
  pm::Json tries = pm::Json::array();
  for (int k = 0; k < max_runs; ++k) {
    pm::CgalMeshResult r = run(p);
    const double n = double(r.surface.vertices.size());
    const double err = std::abs(n / double(target) - 1);
    tries.push_back({{"facet_size", p.facet_size}, {"vertices", r.surface.vertices.size()}, {"seconds", r.seconds}});
    pm::info("facet size " + std::to_string(p.facet_size) + ": " + std::to_string(r.surface.vertices.size()) +
             " vertices (target " + std::to_string(target) + ")");
    if (err < best_err) {
      best_err = err;
      best = std::move(r);
      st["parameters"]["facet_size"] = p.facet_size;
    }
    if (err <= tol) break;
    p.facet_size *= std::pow(n / double(target), 0.5);
  }
  st["size_search"] = tries;
  if (best_err > tol)
    pm::warn("vertex count " + std::to_string(best.surface.vertices.size()) + " is " +
             std::to_string(int(std::lround(100 * best_err))) + "% off the target " + std::to_string(target));
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  pm::Tool tool("baseline",
                "Baseline meshes to compare particle meshes with, on the same volume (world units from its header). "
                "mc: marching cubes of F = iso (OpenVDB volumeToMesh, adaptivity 0, trilinear). cgal: CGAL Mesh_3 "
                "surface mesh of the image isosurface (facet angle 30, facet distance = size/4, manifold), with the "
                "facet size given or searched so the vertex count matches --vertices. cgal-labels: CGAL Mesh_3 on a "
                "label map with the lines where three labels meet protected; writes every interface with face "
                "properties label_a < label_b (0 = outside). Outputs are closed triangle meshes (.ply .obj .off .stl).",
                "baseline cgal -i brain_sdf.nrrd --iso 0 --vertices 100000 -o cgal.ply --stats cgal.json");
  std::string mode, out, inside = "auto";
  pm::FieldOptions fo;
  std::size_t vertices = 0;
  double size = 0, distance = 0, angle = 30, tol = 0.1;
  int max_runs = 5;
  tool.app.add_option("mode", mode, "mc | cgal | cgal-labels")->required()->check(
      CLI::IsMember({"mc", "cgal", "cgal-labels"}));
  tool.app.add_option("-i,--input", fo.input, "Volume (.nrrd .nhdr .vdb .mha .nii .inr); cgal-labels: a label map")
      ->required();
  tool.app.add_option("--iso", fo.iso, "Isovalue (mc, cgal), in voxel value units")->capture_default_str();
  tool.app.add_option("--inside", inside,
                      "Which side is the material (mc, cgal): below (F < iso), above (F > iso) or auto (the side "
                      "the domain's corners are not on)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "below", "above"}));
  tool.app.add_option("-o,--output", out, "Mesh to write (.ply .vtp .vtk .mesh .obj .off .stl), world units")->required();
  tool.app.add_option("--vertices", vertices, "cgal modes: search the facet size so the mesh has about N vertices");
  tool.app.add_option("--size", size, "cgal modes: Mesh_3 facet_size (and edge_size), world units");
  tool.app.add_option("--distance", distance, "cgal modes: Mesh_3 facet_distance, world units (default size/4)");
  tool.app.add_option("--angle", angle, "cgal modes: Mesh_3 facet_angle, degrees")->capture_default_str();
  tool.app.add_option("--vertex-tolerance", tol, "cgal modes with --vertices: accepted relative deviation")
      ->capture_default_str();
  tool.app.add_option("--max-runs", max_runs, "cgal modes with --vertices: most Mesh_3 runs in the size search")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  pm::WorldFrame frame = pm::WorldFrame::lps;
  pm::add_frame_option(tool.app, frame);
  return tool.run(argc, argv, [&] {
    pm::check_output_path(out, pm::OutputKind::mesh, "--output");
    auto& st = pm::stats();
    st["inputs"] = {fo.input};
    st["parameters"] = {{"mode", mode}};
    if (mode != "mc" && (vertices > 0) == (size > 0))
      throw pm::UsageError(mode + ": give exactly one of --vertices N or --size S (world units)");
    if (mode == "mc" && (vertices > 0 || size > 0))
      throw pm::UsageError("mc: --vertices and --size are for the cgal modes; marching cubes uses the voxel grid");
    pm::Mesh m;
    pm::Stopwatch clock;
    pm::CgalMeshParams p;
    p.facet_size = size;
    p.facet_distance = distance;
    p.facet_angle = angle;
    p.threads = tool.flags.threads;
    p.seed = tool.flags.seed;
    if (mode == "cgal-labels") {
      pm::Volume v;
      {
        pm::ScopedStage s("read");
        v = pm::read_volume(fo.input);
      }
      double start = size;
      if (vertices > 0) {
        // Interface area ~ 2/3 of the voxel faces between different labels.
        const pm::Dims d = v.dims();
        const double sp[3] = {v.geometry().spacing(0), v.geometry().spacing(1), v.geometry().spacing(2)};
        double area = 0;
        const std::size_t step[3] = {1, d.nx, d.nx * d.ny};
        for (std::size_t k = 0; k < d.nz; ++k)
          for (std::size_t j = 0; j < d.ny; ++j)
            for (std::size_t i = 0; i < d.nx; ++i) {
              const std::size_t idx = v.index(i, j, k);
              const std::size_t ijk[3] = {i, j, k};
              for (int a = 0; a < 3; ++a)
                if (ijk[a] + 1 < d[a] && v.get(idx) != v.get(idx + step[a]))
                  area += sp[(a + 1) % 3] * sp[(a + 2) % 3];
            }
        if (area == 0) throw pm::InputError(pm::quote(fo.input) + ": a single label; expected a label map with at least two labels");
        start = pm::facet_size_for_vertices(area * 2 / 3, vertices);
      }
      pm::CgalMeshResult r;
      {
        pm::ScopedStage s("cgal");
        r = sized_run([&](const pm::CgalMeshParams& q) { return pm::cgal_labels(v, q); }, p, vertices, start, tol,
                      max_runs, st);
      }
      m = std::move(r.surface);
      st["counts"]["c3t3_vertices"] = r.c3t3_vertices;
      st["counts"]["parallel"] = r.parallel;
      st["seconds_final_run"] = r.seconds;
    } else {
      pm::LoadedField lf;
      pm::Volume v;
      {
        pm::ScopedStage s("read");
        lf = pm::load_field(fo);  // checks the isovalue against the value range
        v = pm::read_volume(fo.input);
      }
      const bool below = inside == "auto" ? pm::material_below_iso(*lf.field, lf.iso) : inside == "below";
      st["parameters"]["iso"] = lf.iso;
      st["parameters"]["inside"] = below ? "below" : "above";
      if (mode == "mc") {
        pm::ScopedStage s("marching_cubes");
        m = pm::marching_cubes_baseline(v, lf.iso, below);
      } else {
        double start = size;
        if (vertices > 0) start = pm::facet_size_for_vertices(pm::mesh_area(pm::marching_cubes_baseline(v, lf.iso, below)), vertices);
        pm::CgalMeshResult r;
        {
          pm::ScopedStage s("cgal");
          r = sized_run([&](const pm::CgalMeshParams& q) { return pm::cgal_isosurface(v, lf.iso, below, q); }, p,
                        vertices, start, tol, max_runs, st);
        }
        m = std::move(r.surface);
        st["counts"]["c3t3_vertices"] = r.c3t3_vertices;
        st["counts"]["parallel"] = r.parallel;
        st["seconds_final_run"] = r.seconds;
      }
    }
    const pm::MeshTopology t = pm::mesh_topology(m);
    pm::write_mesh(m, out, {true, frame});
    pm::info(std::to_string(t.vertices) + " vertices, " + std::to_string(t.faces) + " triangles, " +
             std::to_string(t.components) + " component(s), genus " + std::to_string(t.genus));
    st["outputs"] = {out};
    st["counts"]["vertices"] = t.vertices;
    st["counts"]["faces"] = t.faces;
    st["counts"]["components"] = t.components;
    st["counts"]["genus"] = t.genus;
    st["counts"]["boundary_edges"] = t.boundary_edges;
    st["counts"]["nonmanifold_edges"] = t.nonmanifold_edges;
    st["seconds_total"] = clock.seconds();
  });
}
