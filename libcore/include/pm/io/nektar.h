#pragma once
// Nektar++ spectral/hp element files: the session/mesh XML (GEOMETRY with
// VERTEX, EDGE, FACE, ELEMENT, optional CURVED; each section plain or
// COMPRESSED="B64Z-LittleEndian") and the field file .fld (XML ELEMENTS
// blocks of base64 + zlib coefficients). Parsed with tinyxml2 and zlib.
//
// Element-local vertex order: Nektar++ derives it from the element's faces
// and their edges (TetGeom / HexGeom SetUpLocalEdges + SetUpLocalVertices),
// not from any listing; read_nektar_mesh does the same, so that reference
// coordinates and modal coefficients refer to the same local element.
//
// Reference elements (Nektar++'s): xi in [-1,1]^3. Tetrahedron vertices
// v0(-1,-1,-1) v1(1,-1,-1) v2(-1,1,-1) v3(-1,-1,1); hexahedron vertices
// v0..v3 = (-1,-1,-1) (1,-1,-1) (1,1,-1) (-1,1,-1), v4..v7 the same at xi3 = 1.
#include <array>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "pm/base/vec.h"

namespace pm {

enum class NektarShape { Tetrahedron, Hexahedron };

/// "Tetrahedron" / "Hexahedron" (the names of the .fld SHAPE attribute).
const char* nektar_shape_name(NektarShape s);

struct NektarElement {
  int id = 0;                 ///< global element id (ELEMENT/A or /H ID)
  NektarShape shape = NektarShape::Tetrahedron;
  int nverts = 0;             ///< 4 or 8
  int nfaces = 0;             ///< 4 or 6
  std::array<int, 8> verts{}; ///< vertex ids in Nektar++'s local order
  std::array<int, 6> faces{}; ///< face ids in local face order (the listing order)
  std::array<int, 12> edges{};///< edge ids in local edge order (derived as Nektar++ does)
};

/// A CURVED entry: extra points along an edge or over a face.
struct NektarCurve {
  int id = 0;                ///< curve id
  int entity = 0;            ///< EDGEID or FACEID
  std::string type;          ///< points type, e.g. "PolyEvenlySpaced"
  std::vector<Vec3> points;  ///< NUMPOINTS points, world units
};

struct NektarMesh {
  std::string path;
  int dim = 3;
  std::vector<Vec3> vertices;                       ///< world units
  std::unordered_map<int, int> vertex_index;        ///< vertex id -> index in vertices
  std::unordered_map<int, std::array<int, 2>> edges;  ///< edge id -> vertex ids
  /// face id -> edge ids (3 for T, 4 for Q; unused entries -1).
  std::unordered_map<int, std::array<int, 4>> faces;
  std::vector<NektarElement> elements;              ///< in file order
  std::unordered_map<int, int> element_index;       ///< element id -> index in elements
  std::vector<NektarCurve> curved_edges, curved_faces;
  /// First EXPANSIONS/E entry, when present: NUMMODES, TYPE and FIELDS.
  int expansion_modes = 0;
  std::string expansion_type, expansion_fields;

  const Vec3& vertex(int id) const { return vertices[vertex_index.at(id)]; }
  /// True when one of the element's edges or faces has a CURVED entry;
  /// `what` then names it ("edge 17" / "face 3").
  bool element_curved(const NektarElement& e, std::string* what = nullptr) const;
};

/// Read the GEOMETRY of a Nektar++ session or mesh XML file (3D: tetrahedra
/// A and hexahedra H; vertices scaled/moved by XSCALE.. / XMOVE.. when those
/// are plain numbers). CURVED edges and faces are read (plain and compressed)
/// and kept; the elements are built straight-sided (HpField refuses curved
/// ones by name).
/// \throw IoError when the file cannot be read; InputError naming the file on
/// malformed XML, a missing section, an unknown element or face type (prisms
/// R and pyramids P are refused by name), a bad id, a dangling reference,
/// faces that do not close an element, truncated or corrupt base64/zlib data,
/// or non-finite coordinates.
NektarMesh read_nektar_mesh(const std::string& path);

/// Coefficients of one element in a .fld file.
struct NektarFieldElement {
  int id = 0;
  NektarShape shape = NektarShape::Tetrahedron;
  std::array<int, 3> modes{};  ///< modes per direction (P, Q, R)
  int ncoeffs = 0;             ///< coefficients per field
  std::vector<double> coeffs;  ///< nfields x ncoeffs, [field][mode]
};

struct NektarField {
  std::string path;
  std::vector<std::string> names;  ///< field variables, e.g. u v w p
  std::vector<NektarFieldElement> elements;
  std::unordered_map<int, int> element_index;  ///< element id -> index in elements
  /// Index of variable `name` in names. \throw UsageError listing the names.
  int variable(const std::string& name) const;
};

/// Read a Nektar++ XML field file: every ELEMENTS block (FIELDS, SHAPE
/// Tetrahedron/Hexahedron, BASIS Modified_A,Modified_B,Modified_C for
/// tetrahedra and Modified_A x3 for hexahedra, NUMMODESPERDIR UNIORDER:P,Q,R
/// or MIXORDER with three numbers per element, ID as ranges "0-3,7"), data
/// base64 + zlib little-endian doubles laid out [field][element][mode].
/// \throw IoError when the file cannot be read (a parallel .fld folder is
/// refused); InputError naming the file on malformed XML, a missing
/// attribute or block, an unknown shape or basis, a coefficient count that
/// does not match the modes, an element given twice, truncated or corrupt
/// base64/zlib data, or a non-finite coefficient.
NektarField read_nektar_field(const std::string& path);

/// Number of modal coefficients of a Modified expansion with modes (P, Q, R):
/// P*Q*R for hexahedra, sum_{p<P} sum_{q<Q-p} (R-p-q) for tetrahedra.
int nektar_num_coeffs(NektarShape s, const std::array<int, 3>& modes);

/// Check that every element of `field` exists in `mesh` with the same shape.
/// \throw InputError naming the field file and the first offending element id.
void check_field_matches_mesh(const NektarField& field, const NektarMesh& mesh);

/// Nektar++'s "B64Z-LittleEndian" encoding: zlib-compress bytes, then base64
/// (standard alphabet, no '=' padding, the binary zero-padded to a multiple
/// of 3 first, as Nektar++ writes it).
std::string nektar_b64z_encode(const void* data, std::size_t n);
/// Inverse of nektar_b64z_encode; accepts '=' padding and whitespace.
/// `what` prefixes the messages. \throw InputError on a bad base64 character,
/// a truncated base64 string, or truncated or corrupt zlib data.
std::vector<unsigned char> nektar_b64z_decode(const std::string& text, const std::string& what);

}  // namespace pm
