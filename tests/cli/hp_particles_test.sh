#!/usr/bin/env bash
# particles --field (Chapter 4) end to end on the shared Nektar++ chan3D field
# (u = 1 - z^2): the double PLY read by meshio puts every particle on
# |z| = 1/sqrt(2) to 1e-12 with its element id and residual; 1 and 2 threads (3.7k particles,
# above the engine's serial threshold of 2,000)
# give identical bytes; bad input gives one error line naming the file, exit 1
# (2 for usage errors), and no output. Skips (77) without the shared data.
set -euo pipefail
BIN=$1; SRC=$2
P="$BIN/particles"
D="$SRC/../shared/data/nektar-highorder"
[ -f "$D/chan3D.xml" ] || { echo "hp_particles_test: shared data absent: $D (skipped)"; exit 77; }
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "hp_particles_test: $*" >&2; exit 1; }

for t in 1 2; do
  "$P" -i "$D/chan3D.xml" --field "$D/chan3D.fld:u" --iso 0.5 --spacing 0.05 --threads $t -o "$T/u$t.ply" -q \
    --stats "$T/u$t.json"
done
cmp -s "$T/u1.ply" "$T/u2.ply" || fail "1 and 2 threads give different files"
head -c 400 "$T/u1.ply" | grep -q "property double x" || fail "positions are not written as double"
/usr/bin/python3 - "$T/u1.ply" "$T/u1.json" <<'PY' || fail "chan3D particles are not on |z| = 1/sqrt(2)"
import json, sys
import numpy as np
try:
    import meshio
except ImportError:
    sys.exit(0)
m = meshio.read(sys.argv[1])
p = m.points
assert p.dtype == np.float64, p.dtype
assert len(p) > 3000, len(p)
err = np.abs(np.abs(p[:, 2]) - 2 ** -0.5).max()
assert err <= 1e-12, err
for k in ("element", "xi1", "xi2", "xi3", "residual", "nx"):
    assert k in m.point_data, (k, list(m.point_data))
assert m.point_data["residual"].max() <= 1e-12
assert set(np.unique(m.point_data["element"]).astype(int)) == set(range(6)), np.unique(m.point_data["element"])
d = json.load(open(sys.argv[2]))
assert d["counts"]["particles"] == len(p) and d["max_residual"] <= 1e-12, d["counts"]
PY

# Bad input: one line "particles: error: ..." naming the file, exit 1, no output.
expect() {  # code, regex, args...
  local code=$1 re=$2; shift 2
  set +e
  "$P" "$@" -o "$T/bad.ply" -q 2>"$T/err"
  local rc=$?
  set -e
  [ "$rc" = "$code" ] || fail "exit $rc (want $code) for $*: $(cat "$T/err")"
  [ "$(wc -l <"$T/err")" = 1 ] || fail "not one error line for $*: $(cat "$T/err")"
  grep -Eq "$re" "$T/err" || fail "message for $* does not match '$re': $(cat "$T/err")"
  [ ! -e "$T/bad.ply" ] || fail "output written for $*"
  ls "$T" | grep -q '\.tmp' && fail "temporary file left for $*" || true
}
expect 1 'particles: error: .*chan3D.fld.* has no variable "T"; expected one of: u v w p' \
  -i "$D/chan3D.xml" --field "$D/chan3D.fld:T" --iso 0.5 --spacing 0.1
expect 1 'particles: error: .*Tet_channel_m3.fld' \
  -i "$D/chan3D.xml" --field "$D/Tet_channel_m3.fld:u" --iso 0.5 --spacing 0.1
expect 1 'particles: error: .*no isosurface F = 3 .*chan3D.xml:u' \
  -i "$D/chan3D.xml" --field "$D/chan3D.fld:u" --iso 3 --spacing 0.1
expect 1 'particles: error: .*nope.fld' \
  -i "$D/chan3D.xml" --field "$T/nope.fld:u" --iso 0.5 --spacing 0.1
expect 2 'particles: usage error: --field expects FILE.fld:VARIABLE' \
  -i "$D/chan3D.xml" --field "$D/chan3D.fld" --iso 0.5 --spacing 0.1
# A curved edge: Tet_channel_m3.xml with a CURVED block on edge 0.
/usr/bin/python3 - "$D/Tet_channel_m3.xml" "$T/curved.xml" <<'PY'
import re, sys
s = open(sys.argv[1]).read()
curved = ('<CURVED><E ID="0" EDGEID="0" TYPE="PolyEvenlySpaced" NUMPOINTS="3">'
          '0 0 0 0.05 0.05 0.02 0.1 0.1 0.05</E></CURVED>')
s2 = re.sub(r"(</ELEMENT>)", r"\1" + curved, s, count=1)
assert s2 != s
open(sys.argv[2], "w").write(s2)
PY
expect 1 'particles: error: .*curved.xml.*curved edge 0; curved elements are not supported' \
  -i "$T/curved.xml" --field "$D/Tet_channel_m3.fld:w" --iso 0.2 --spacing 0.1
echo "hp_particles_test: ok"
