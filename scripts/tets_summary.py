"""The last line of a `tets` / `materials-tets` run: counts and quality of
the volume mesh from meshstats' JSON (argv[1]), and where it is (argv[2])."""
import json
import sys

q = json.load(open(sys.argv[1]))
o = q["overall"]
checks = [k for k in ("positive", "boundary_manifold", "triangles_match") if q.get(k) is False]
print(f'tets: {q["vertices"]} vertices, {o["tets"]} tetrahedra in {len(q["materials"])} material(s), '
      f'dihedral {o["dihedral_min"]:.1f}-{o["dihedral_max"]:.1f} deg, rr min {o["rr_min"]:.3f} mean {o["rr_mean"]:.3f}, '
      f'{100 * o["share_under_10"]:.2f}% under 10 deg'
      + (f'; FAILED: {", ".join(checks)}' if checks else '') + f'; {sys.argv[2]}')
