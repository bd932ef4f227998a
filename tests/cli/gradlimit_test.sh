#!/usr/bin/env bash
# End-to-end gradlimit checks: a spike sizing field with anisotropic spacing
# becomes the cone min(10, 1 + delta |x - c|), the output is delta-Lipschitz
# and never above the input, unknown voxels (h <= 0) are extended, and a
# failed run leaves nothing.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
GL="$BIN/gradlimit"

# Spike field 15 x 11 x 21, spacing 1 2 0.5: h = 10, h = 1 at (7,5,10); the
# slab x >= 13 is unknown (0).
python3 - "$T/spike.nrrd" <<'PY'
import sys
nx, ny, nz = 15, 11, 21
v = []
for k in range(nz):
    for j in range(ny):
        for i in range(nx):
            v.append(1.0 if (i, j, k) == (7, 5, 10) else (0.0 if i >= 13 else 10.0))
with open(sys.argv[1], "w") as f:
    f.write("NRRD0004\ntype: float\ndimension: 3\nsizes: %d %d %d\nspacings: 1 2 0.5\nencoding: ascii\n\n" % (nx, ny, nz))
    f.write(" ".join("%g" % x for x in v) + "\n")
PY
"$GL" "$T/spike.nrrd" "$T/out.nrrd" --delta 0.3 --stats "$T/st.json" -q
python3 - "$T/spike.nrrd" "$T/out.nrrd" "$T/st.json" <<'PY'
import gzip, json, math, struct, sys

def read_nrrd(path):
    raw = open(path, "rb").read()
    head, _, data = raw.partition(b"\n\n")
    h = {}
    for line in head.decode().splitlines()[1:]:
        if ":" in line and not line.startswith("#"):
            k, _, val = line.partition(":")
            h[k.strip()] = val.strip().lstrip("=")
    sizes = [int(s) for s in h["sizes"].split()]
    n = sizes[0] * sizes[1] * sizes[2]
    enc = h["encoding"]
    if enc == "ascii":
        vals = [float(x) for x in data.split()]
    else:
        if enc in ("gzip", "gz"):
            data = gzip.decompress(data)
        assert h.get("type") == "float", h
        fmt = ("<" if h.get("endian", "little") == "little" else ">") + "%df" % n
        vals = list(struct.unpack(fmt, data[: 4 * n]))
    assert len(vals) == n, (len(vals), n)
    return sizes, vals

(nx, ny, nz), h0 = read_nrrd(sys.argv[1])
_, h = read_nrrd(sys.argv[2])
st = json.load(open(sys.argv[3]))
sp = (1.0, 2.0, 0.5)
at = lambda i, j, k: i + nx * (j + ny * k)
worst = 0.0
for k in range(nz):
    for j in range(ny):
        for i in range(nx):
            v = h[at(i, j, k)]
            assert v > 0, (i, j, k, v)
            if h0[at(i, j, k)] > 0:
                assert v <= h0[at(i, j, k)] * (1 + 1e-6), (i, j, k)
            for a, (di, dj, dk) in enumerate(((1, 0, 0), (0, 1, 0), (0, 0, 1))):
                if i + di < nx and j + dj < ny and k + dk < nz:
                    worst = max(worst, abs(h[at(i + di, j + dj, k + dk)] - v) / sp[a])
            cone = min(10.0, 1 + 0.3 * math.sqrt(((i - 7) * sp[0]) ** 2 + ((j - 5) * sp[1]) ** 2 + ((k - 10) * sp[2]) ** 2))
            if i < 13:
                assert abs(v - cone) < 1e-4, (i, j, k, v, cone)
assert worst <= 0.3 * 1.01, worst
c = st["counts"]
assert c["unknown"] == 2 * ny * nz and c["known"] == 13 * ny * nz, c
assert c["max_slope_over_delta"] <= 1 + 1e-5, c  # float rounding: ~1e-7 * 10 / (0.3 * 0.5)
# Unknown voxels next to the spike row get the cone, the rest 10 + 0.3 * distance to x = 12.
assert abs(h[at(13, 5, 10)] - (1 + 0.3 * 6)) < 1e-4, h[at(13, 5, 10)]
assert abs(h[at(14, 0, 0)] - min(1 + 0.3 * math.sqrt(49 + 100 + 25), 10 + 0.3 * 2)) < 1e-4, h[at(14, 0, 0)]
PY

# The output is raw by default; --gzip compresses it, same values.
grep -a -m1 "^encoding: raw" "$T/out.nrrd" >/dev/null || { echo "default output not raw"; exit 1; }
"$GL" "$T/spike.nrrd" "$T/out_gz.nrrd" --delta 0.3 --gzip -q
grep -a -m1 "^encoding: gzip" "$T/out_gz.nrrd" >/dev/null || { echo "--gzip output not gzip"; exit 1; }
python3 - "$T/out.nrrd" "$T/out_gz.nrrd" <<'PY'
import gzip, sys
a = open(sys.argv[1], "rb").read().partition(b"\n\n")[2]
b = gzip.decompress(open(sys.argv[2], "rb").read().partition(b"\n\n")[2])
assert a == b, "raw and --gzip outputs differ"
PY

# A failed run leaves no output and no temporary file.
mkdir "$T/fail"
if "$GL" "$SRC/tests/data/zeros.nrrd" "$T/fail/out.nrrd" 2>/dev/null; then echo "all-unknown input accepted"; exit 1; fi
[ -z "$(ls -A "$T/fail")" ] || { echo "left behind: $(ls -A "$T/fail")"; exit 1; }
echo "gradlimit workflow: ok"
