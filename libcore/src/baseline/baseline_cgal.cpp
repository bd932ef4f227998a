// All CGAL Mesh_3 includes for the baselines live here: they compile slowly.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Image_3.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_domain_with_polyline_features_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Random.h>
#include <CGAL/make_mesh_3.h>
// After make_mesh_3.h: the parallel exuder needs its worksharing structures.
#include <CGAL/exude_mesh_3.h>
#include <CGAL/perturb_mesh_3.h>

#include <cmath>
#include <map>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/baseline/baseline.h"
#include "pm/mesh/tet_quality.h"

namespace pm {

namespace {

#ifdef CGAL_LINKED_WITH_TBB
using Concurrency = CGAL::Parallel_tag;
constexpr bool kParallel = true;
#else
using Concurrency = CGAL::Sequential_tag;
constexpr bool kParallel = false;
#endif

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using ImageDomain = CGAL::Labeled_mesh_domain_3<K>;
using FeatureDomain = CGAL::Mesh_domain_with_polyline_features_3<ImageDomain>;

// Our volume as a CGAL image (node samples, voxel i at origin + i * spacing).
// CGAL's images hold positive spacings only: callers pass with_positive_steps(v).
template <class T>
CGAL::Image_3 make_image(const Volume& v, WORD_KIND kind, SIGN sign, const std::vector<T>& data) {
  const Geometry& g = v.geometry();
  if (!g.axis_aligned() || g.directions[0][0] <= 0 || g.directions[1][1] <= 0 || g.directions[2][2] <= 0)
    throw InputError("CGAL Mesh_3 baseline: the volume's space directions are not axis-aligned with positive "
                     "spacings; expected a diagonal direction matrix (resample it first)");
  _image* im = ::_createImage(v.dims().nx, v.dims().ny, v.dims().nz, 1, g.spacing(0), g.spacing(1), g.spacing(2),
                              sizeof(T), kind, sign);
  if (im == nullptr) throw Error("CGAL Mesh_3 baseline: cannot allocate the image");
  std::copy(data.begin(), data.end(), static_cast<T*>(im->data));
  im->tx = float(g.origin.x);
  im->ty = float(g.origin.y);
  im->tz = float(g.origin.z);
  return CGAL::Image_3(im);
}

// Vertices of the triangulation numbered in order of first use, their
// positions appended to `out`.
template <class Tr>
class VertexIndex {
 public:
  VertexIndex(const Tr& tr, std::vector<Vec3>& out) : tr_(tr), out_(out) {}
  int operator()(typename Tr::Vertex_handle v) {
    auto it = index_.find(v);
    if (it != index_.end()) return it->second;
    const auto& p = tr_.point(v);
    out_.push_back({CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z())});
    index_.emplace(v, int(out_.size()) - 1);
    return int(out_.size()) - 1;
  }

 private:
  const Tr& tr_;
  std::vector<Vec3>& out_;
  std::map<typename Tr::Vertex_handle, int> index_;
};

// The complex's facets between two different subdomains (0 = outside), each
// oriented so its normal points from the lower to the higher subdomain
// index, with those two indices.
template <class C3t3>
void interface_facets(const C3t3& c3t3, VertexIndex<typename C3t3::Triangulation>& vid,
                      const std::vector<Vec3>& vertices, std::vector<std::array<int, 3>>& faces,
                      std::vector<int>& la, std::vector<int>& lb) {
  using Tr = typename C3t3::Triangulation;
  const Tr& tr = c3t3.triangulation();
  for (auto fit = c3t3.facets_in_complex_begin(); fit != c3t3.facets_in_complex_end(); ++fit) {
    auto c = fit->first;
    int i = fit->second;
    auto mirror = c->neighbor(i);
    const int mi = mirror->index(c);
    int sc = c3t3.is_in_complex(c) ? int(c3t3.subdomain_index(c)) : 0;
    int sm = c3t3.is_in_complex(mirror) ? int(c3t3.subdomain_index(mirror)) : 0;
    if (sc == sm) continue;
    // Orient towards the higher index: view the facet from the lower side.
    // Use a finite cell's opposite vertex to decide the winding.
    const bool c_low = sc < sm;
    auto cell = tr.is_infinite(c) ? mirror : c;
    const int ci = tr.is_infinite(c) ? mi : i;
    const bool cell_low = (cell == c) ? c_low : !c_low;
    std::array<int, 3> f;
    for (int k = 0; k < 3; ++k) f[std::size_t(k)] = vid(cell->vertex(Tr::vertex_triple_index(ci, k)));
    const Vec3 &a = vertices[std::size_t(f[0])], &b = vertices[std::size_t(f[1])], &cc = vertices[std::size_t(f[2])];
    const auto& q = tr.point(cell->vertex(ci));
    const Vec3 opp{CGAL::to_double(q.x()), CGAL::to_double(q.y()), CGAL::to_double(q.z())};
    const bool points_into_cell = dot(cross(b - a, cc - a), opp - a) > 0;
    // The normal must point out of the low side: into the cell iff the cell is the high side.
    if (points_into_cell == cell_low) std::swap(f[1], f[2]);
    faces.push_back(f);
    la.push_back(std::min(sc, sm));
    lb.push_back(std::max(sc, sm));
  }
}

// Facets of the complex as a mesh (see interface_facets). With `interfaces`,
// face ints label_a/label_b are set.
template <class C3t3>
Mesh extract_facets(const C3t3& c3t3, bool interfaces) {
  Mesh m;
  VertexIndex<typename C3t3::Triangulation> vid(c3t3.triangulation(), m.vertices);
  std::vector<int> la, lb;
  interface_facets(c3t3, vid, m.vertices, m.faces, la, lb);
  if (interfaces) {
    m.face_ints["label_a"] = std::move(la);
    m.face_ints["label_b"] = std::move(lb);
  }
  return m;
}

// The cells in the complex (material = subdomain index, positively oriented)
// and the facets between subdomains with their label pairs.
template <class C3t3>
LabelledTets extract_volume(const C3t3& c3t3) {
  LabelledTets t;
  VertexIndex<typename C3t3::Triangulation> vid(c3t3.triangulation(), t.vertices);
  for (auto cit = c3t3.cells_in_complex_begin(); cit != c3t3.cells_in_complex_end(); ++cit) {
    std::array<int, 4> c{vid(cit->vertex(0)), vid(cit->vertex(1)), vid(cit->vertex(2)), vid(cit->vertex(3))};
    const Vec3& a = t.vertices[std::size_t(c[0])];
    if (dot(cross(t.vertices[std::size_t(c[1])] - a, t.vertices[std::size_t(c[2])] - a),
            t.vertices[std::size_t(c[3])] - a) < 0)
      std::swap(c[2], c[3]);
    t.tets.push_back(c);
    t.materials.push_back(int(c3t3.subdomain_index(cit)));
  }
  std::vector<int> la, lb;
  interface_facets(c3t3, vid, t.vertices, t.triangles, la, lb);
  for (std::size_t i = 0; i < la.size(); ++i) t.triangle_labels.push_back({la[i], lb[i]});
  return t;
}

// One measured step of the volume mesh.
template <class C3t3>
void measure_step(const C3t3& c3t3, const std::string& name, double seconds, CgalMeshResult& res) {
  ConformStep st;
  st.name = name;
  st.seconds = seconds;
  res.volume = extract_volume(c3t3);
  st.vertices = res.volume.vertices.size();
  st.tets = res.volume.tets.size();
  st.quality = tet_quality(res.volume);
  const TetStats& o = st.quality.overall;
  st.share_25_140 = o.share_25_140();
  info("cgal " + name + ": " + std::to_string(st.tets) + " tetrahedra, " + std::to_string(st.vertices) +
       " vertices, dihedral " + std::to_string(o.dihedral_min) + ".." + std::to_string(o.dihedral_max) + " deg, " +
       std::to_string(100 * st.share_25_140) + "% in [25, 140], radius ratio mean " + std::to_string(o.rr_mean) +
       ", " + std::to_string(seconds) + " s");
  res.steps.push_back(std::move(st));
}

const char* optimisation_code(CGAL::Mesh_optimization_return_code c) {
  switch (c) {
    case CGAL::BOUND_REACHED: return "bound reached";
    case CGAL::TIME_LIMIT_REACHED: return "time limit reached";
    case CGAL::CANT_IMPROVE_ANYMORE: return "cannot improve any more";
    case CGAL::CONVERGENCE_REACHED: return "converged";
    case CGAL::MAX_ITERATION_NUMBER_REACHED: return "iteration limit reached";
    case CGAL::ALL_VERTICES_FROZEN: return "all vertices frozen";
    default: return "unknown error";
  }
}

// make_mesh_3 without optimisation, then (volume meshes) perturb and exude,
// each measured. `what` names the mesher in messages.
template <class C3t3, class Domain>
C3t3 mesh_3(const Domain& domain, const CgalMeshParams& p, bool manifold, CgalMeshResult& res,
            const std::string& what) {
  namespace params = CGAL::parameters;
  using Criteria = CGAL::Mesh_criteria_3<typename C3t3::Triangulation>;
  const double dist = p.facet_distance > 0 ? p.facet_distance : p.facet_size / 4;
  const double edge = p.edge_size > 0 ? p.edge_size : p.facet_size;
  const double radius_edge = p.volume ? p.cell_radius_edge : 0;  // 0: no cell refinement
  const double cell_size = p.volume ? p.cell_size : 0;
  Criteria criteria(params::edge_size = edge, params::facet_angle = p.facet_angle, params::facet_size = p.facet_size,
                    params::facet_distance = dist, params::cell_radius_edge_ratio = radius_edge,
                    params::cell_size = cell_size);
  Stopwatch clock;
  C3t3 c3t3;
  try {
    c3t3 = manifold ? CGAL::make_mesh_3<C3t3>(domain, criteria, params::no_perturb(), params::no_exude(),
                                              params::manifold())
                    : CGAL::make_mesh_3<C3t3>(domain, criteria, params::no_perturb(), params::no_exude());
  } catch (const std::exception& e) {
    throw InputError(what + ": CGAL make_mesh_3 failed: " + e.what());
  }
  if (!p.volume) return c3t3;
  measure_step(c3t3, "refine", clock.seconds(), res);
  if (p.optimise) {
    try {
      clock = Stopwatch();
      CGAL::Mesh_optimization_return_code c =
          CGAL::perturb_mesh_3(c3t3, domain, params::time_limit = p.optimise_seconds);
      info(std::string("cgal perturb: ") + optimisation_code(c));
      measure_step(c3t3, "perturb", clock.seconds(), res);
      clock = Stopwatch();
      c = CGAL::exude_mesh_3(c3t3, params::time_limit = p.optimise_seconds);
      info(std::string("cgal exude: ") + optimisation_code(c));
      measure_step(c3t3, "exude", clock.seconds(), res);
    } catch (const std::exception& e) {
      throw InputError(what + ": CGAL sliver perturbation/exudation failed: " + e.what());
    }
  }
  return c3t3;
}

void check_params(const CgalMeshParams& p) {
  if (!(p.facet_size > 0) || !std::isfinite(p.facet_size))
    throw UsageError("CGAL Mesh_3 baseline: facet size must be > 0 world units, got " + std::to_string(p.facet_size));
  if (p.facet_distance < 0)
    throw UsageError("CGAL Mesh_3 baseline: facet distance must be >= 0, got " + std::to_string(p.facet_distance));
  if (!(p.facet_angle > 0 && p.facet_angle <= 30))
    throw UsageError("CGAL Mesh_3 baseline: facet angle must be in (0, 30] degrees, got " +
                     std::to_string(p.facet_angle));
  if (p.volume && !(p.cell_radius_edge >= 2))
    throw UsageError("CGAL Mesh_3 baseline: cell radius-edge ratio must be >= 2 (CGAL's termination bound), got " +
                     std::to_string(p.cell_radius_edge));
  if (p.volume && !(p.cell_size >= 0))
    throw UsageError("CGAL Mesh_3 baseline: cell size must be >= 0 world units (0: none), got " +
                     std::to_string(p.cell_size));
  if (!(p.optimise_seconds >= 0))
    throw UsageError("CGAL Mesh_3 baseline: optimisation time limit must be >= 0 s (0: none), got " +
                     std::to_string(p.optimise_seconds));
}

// The label at most of the 8 corner voxels (ties: the smallest).
int corner_label(const Volume& v, const std::vector<std::int32_t>& data) {
  const Dims d = v.dims();
  std::map<int, int> votes;
  for (std::size_t k : {std::size_t(0), d.nz - 1})
    for (std::size_t j : {std::size_t(0), d.ny - 1})
      for (std::size_t i : {std::size_t(0), d.nx - 1}) ++votes[data[v.index(i, j, k)]];
  int best = 0, n = -1;
  for (const auto& [l, c] : votes)
    if (c > n) {
      best = l;
      n = c;
    }
  return best;
}

// Material side as Mesh_3 subdomain 1, outside 0.
struct SideOf {
  double iso;
  bool below;
  int operator()(double v) const { return (below ? v < iso : v > iso) ? 1 : 0; }
};

}  // namespace

CgalMeshResult cgal_isosurface(const Volume& input, double iso, bool material_below, const CgalMeshParams& p) {
  check_params(p);
  // Flipped axes (a RAS NIfTI in LPS) reversed for CGAL; oblique ones are refused in make_image.
  const Volume v = input.geometry().axis_aligned() ? with_positive_steps(input, "CGAL Mesh_3 baseline") : input;
  namespace params = CGAL::parameters;
  Stopwatch clock;
  const std::vector<float> data = v.to_float();
  CGAL::Image_3 image = make_image<float>(v, WK_FLOAT, SGN_SIGNED, data);
  const ValueRange r = value_range(v);
  if (!(iso > r.lo && iso < r.hi))
    throw InputError("CGAL Mesh_3 baseline: isovalue " + std::to_string(iso) + " is outside the value range [" +
                     std::to_string(r.lo) + ", " + std::to_string(r.hi) + "]; expected a value strictly inside");
  // Outside the image counts as outside the material.
  const double outside = material_below ? r.hi + 1 : r.lo - 1;
  CGAL::get_default_random() = CGAL::Random(unsigned(p.seed));
  ImageDomain domain = ImageDomain::create_gray_image_mesh_domain(
      image, params::iso_value = iso, params::image_values_to_subdomain_indices = SideOf{iso, material_below},
      params::value_outside = outside, params::relative_error_bound = 1e-6);
  using Tr = CGAL::Mesh_triangulation_3<ImageDomain, CGAL::Default, Concurrency>::type;
  using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
  CgalMeshResult res;
  const C3t3 c3t3 = mesh_3<C3t3>(domain, p, true, res, "CGAL Mesh_3 baseline");
  res.surface = extract_facets(c3t3, false);
  // extract_facets orients from subdomain 0 (outside) into 1 (the material): flip to point outward.
  for (auto& f : res.surface.faces) std::swap(f[1], f[2]);
  if (res.surface.faces.empty())
    throw InputError("CGAL Mesh_3 baseline: no surface found at F = " + std::to_string(iso) +
                     "; expected the isovalue to cross the volume");
  res.c3t3_vertices = c3t3.triangulation().number_of_vertices();
  res.seconds = clock.seconds();
  res.parallel = kParallel;
  return res;
}

CgalMeshResult cgal_labels(const Volume& input, const CgalMeshParams& p) {
  const Volume labels = input.geometry().axis_aligned() ? with_positive_steps(input, "CGAL Mesh_3 baseline") : input;
  check_params(p);
  namespace params = CGAL::parameters;
  if (!is_integer(labels.type()))
    throw InputError(std::string("CGAL Mesh_3 labels baseline: voxel type ") + voxel_type_name(labels.type()) +
                     "; expected an integer label map");
  const ValueRange r = value_range(labels);
  if (r.lo == r.hi) throw InputError("CGAL Mesh_3 labels baseline: a single label; expected at least two");
  if (r.lo < 0 || r.hi > 2147483647.0)
    throw InputError("CGAL Mesh_3 labels baseline: labels in [" + std::to_string(r.lo) + ", " +
                     std::to_string(r.hi) + "]; expected non-negative 32-bit labels");
  Stopwatch clock;
  const std::vector<std::vector<Vec3>> lines = triple_lines(labels);
  std::vector<std::vector<K::Point_3>> polylines;
  for (const auto& l : lines) {
    if (l.size() < 2) continue;
    std::vector<K::Point_3> pl;
    for (const Vec3& x : l) pl.emplace_back(x.x, x.y, x.z);
    polylines.push_back(std::move(pl));
  }
  debug(std::to_string(polylines.size()) + " triple-line polylines protected");
  std::vector<std::int32_t> data(labels.count());
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = std::int32_t(labels.get(i));
  // CGAL's outside is label 0: the outside label trades places with it.
  const int outside = p.outside_label >= 0 ? p.outside_label : corner_label(labels, data);
  if (outside != 0)
    for (std::int32_t& x : data) x = x == outside ? 0 : (x == 0 ? outside : x);
  CGAL::Image_3 image = make_image<std::int32_t>(labels, WK_FIXED, SGN_SIGNED, data);
  CGAL::get_default_random() = CGAL::Random(unsigned(p.seed));
  FeatureDomain domain = FeatureDomain::create_labeled_image_mesh_domain(image, params::relative_error_bound = 1e-6);
  domain.add_features(polylines.begin(), polylines.end());
  using Tr = CGAL::Mesh_triangulation_3<FeatureDomain, CGAL::Default, Concurrency>::type;
  using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr, FeatureDomain::Corner_index, FeatureDomain::Curve_index>;
  CgalMeshResult res;
  const C3t3 c3t3 = mesh_3<C3t3>(domain, p, false, res, "CGAL Mesh_3 labels baseline");
  res.surface = extract_facets(c3t3, true);
  if (res.surface.faces.empty())
    throw InputError("CGAL Mesh_3 labels baseline: no interface facets; expected at least two labelled regions");
  if (outside != 0) {
    auto back = [&](int x) { return x == 0 ? outside : (x == outside ? 0 : x); };
    auto& la = res.surface.face_ints["label_a"];
    auto& lb = res.surface.face_ints["label_b"];
    for (std::size_t f = 0; f < la.size(); ++f) {
      la[f] = back(la[f]);
      lb[f] = back(lb[f]);
      if (la[f] > lb[f]) {  // keep label_a < label_b, the normal from a into b
        std::swap(la[f], lb[f]);
        std::swap(res.surface.faces[f][1], res.surface.faces[f][2]);
      }
    }
    for (int& m : res.volume.materials) m = back(m);
    for (auto& pr : res.volume.triangle_labels) {
      pr = {back(pr[0]), back(pr[1])};
      if (pr[0] > pr[1]) std::swap(pr[0], pr[1]);
    }
  }
  res.c3t3_vertices = c3t3.triangulation().number_of_vertices();
  res.seconds = clock.seconds();
  res.parallel = kParallel;
  return res;
}

}  // namespace pm
