#!/usr/bin/env bash
# Issue 21: thick slices must not add creases. The iso2mesh brain mask (1 mm) resampled to
# 2 x 2 x 4 mm (every 2nd voxel in x and y, every 4th in z) and to 4 x 4 x 4 mm goes through
# `make materials` with the defaults. R comes from the header (4 mm on both), and the
# anisotropic map's share of interface edges bending by more than 20 degrees must not exceed
# the isotropic 4 mm map's (measured 1.3% against 1.8% with the defaults of 2026-12-03, HMIN = R/2,
# EPS 0.3, DELTA 0.05; 9.2% against 12.2% with the 2008 sizing; the old default R = 1 gave 14.7%,
# slice terraces). The absolute 3% target: cli.pipeline.anisotropic_creases.
# Skipped when the shared data is absent.
set -euo pipefail
BIN=$1; SRC=$2
BRAIN="$SRC/../shared/data/iso2mesh-head/derived/brain.nrrd"
[ -f "$BRAIN" ] || { echo "SKIP: $BRAIN not present"; exit 0; }
[ -x "$BIN/multiparticles" ] || { echo "SKIP: multiparticles not built"; exit 0; }
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
/usr/bin/python3 - "$BRAIN" "$T" <<'PY'
import gzip, sys
import numpy as np
raw = open(sys.argv[1], "rb").read()
head, data = raw.split(b"\n\n", 1)
fields = dict(l.split(": ", 1) for l in head.decode().splitlines()[1:] if ": " in l)
nx, ny, nz = map(int, fields["sizes"].split())
v = np.frombuffer(gzip.decompress(data), np.uint8).reshape(nz, ny, nx)
for name, (sx, sy, sz) in (("b224", (2, 2, 4)), ("b444", (4, 4, 4))):
    s = v[::sz, ::sy, ::sx]
    lo = [max(0, int(a.min()) - 4) for a in np.nonzero(s)]  # cropped to the brain plus 4 voxels
    hi = [int(a.max()) + 5 for a in np.nonzero(s)]
    s = np.ascontiguousarray(s[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]])
    with open(f"{sys.argv[2]}/{name}.nrrd", "wb") as o:
        o.write(f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: {s.shape[2]} {s.shape[1]} {s.shape[0]}\n"
                f"spacings: {sx} {sy} {sz}\nencoding: raw\n\n".encode() + s.tobytes())
PY
for b in b224 b444; do
  make -s -f "$SRC/Makefile.pipeline" materials INPUT="$T/$b.nrrd" OUT="$T/$b" BIN="$BIN" REQUIRE=watertight \
    2> "$T/$b.err" || { cat "$T/$b.err" >&2; exit 1; }
done
python3 - "$T" <<'PY'
import json, sys
t = sys.argv[1]
c = {}
for b in ("b224", "b444"):
    r = json.load(open(f"{t}/{b}/work/tighten.json"))["parameters"]["radius"]
    assert r == 4, f"{b}: tighten radius {r}; expected the largest spacing, 4 mm"
    q = json.load(open(f"{t}/{b}/quality.json"))
    c[b] = q["interfaces"]["crease_share_20"]
    print(f"{b}: crease_share_20 {100 * c[b]:.2f}%, vertices {q['overall']['vertices']}")
assert c["b224"] <= c["b444"], f"thick slices add creases: {c}"
PY
