#!/usr/bin/env bash
# End-to-end render checks: every mode writes a PNG of the requested size that
# shows something, and failed runs exit 1 (bad data) or 2 (usage) leaving no PNG.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
R="$BIN/render"
D="$SRC/tests/data"

# check_png FILE W H: right size, and between 1% and 90% of the pixels are not background.
check_png() {
  python3 - "$@" <<'PY'
import struct, sys, zlib
path, w, h = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
data = open(path, "rb").read()
assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
pos, idat, hdr = 8, b"", None
while pos < len(data):
    n, kind = struct.unpack(">I4s", data[pos:pos + 8])
    body = data[pos + 8:pos + 8 + n]
    if kind == b"IHDR": hdr = struct.unpack(">IIBBBBB", body)
    if kind == b"IDAT": idat += body
    pos += 12 + n
assert hdr[:2] == (w, h), f"size {hdr[:2]}, expected {(w, h)}"
assert hdr[2:5] == (8, 2, 0), f"expected 8-bit RGB, got {hdr[2:5]}"
raw, stride, bpp = zlib.decompress(idat), 3 * w, 3
prev, rows, i = bytearray(stride), [], 0
for _ in range(h):
    f, line = raw[i], bytearray(raw[i + 1:i + 1 + stride]); i += 1 + stride
    for x in range(stride):
        a = line[x - bpp] if x >= bpp else 0
        b, c = prev[x], (prev[x - bpp] if x >= bpp else 0)
        if f == 1: line[x] = (line[x] + a) & 255
        elif f == 2: line[x] = (line[x] + b) & 255
        elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
        elif f == 4:
            p = a + b - c; pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
            line[x] = (line[x] + (a if pa <= pb and pa <= pc else (b if pb <= pc else c))) & 255
    rows.append(line); prev = line
fg = sum(1 for r in rows for x in range(0, stride, 3) if r[x:x + 3] != b"\xff\xff\xff")
assert 0.01 * w * h < fg < 0.9 * w * h, f"{fg} of {w * h} pixels are not background"
PY
}

"$R" -q "$D/sphere_points.ply" -o "$T/splats.png" --size 120x90
check_png "$T/splats.png" 120 90
"$R" -q "$D/sphere_points.ply" -o "$T/disks.png" --size 64x64 --mode disks --color-by height --azimuth 200 --elevation -30
check_png "$T/disks.png" 64 64
"$R" -q "$D/tet.off" -o "$T/mesh.png" --size 100x100 --edges --up y
check_png "$T/mesh.png" 100 100
"$R" -q "$D/tet.off" -o "$T/vertices.png" --size 50x70 --mode splats --radius 0.2
check_png "$T/vertices.png" 50 70

# Failures: exit codes and nothing left behind.
set +e
"$R" -q "$D/sphere_points.ply" -o "$T/bad.png" --color-by nope 2>/dev/null; c1=$?
"$R" -q "$D/sphere_points.ply" -o "$T/bad.png" --size 0x5 2>/dev/null; c2=$?
"$R" -q "$D/nope.ply" -o "$T/bad.png" 2>/dev/null; c3=$?
set -e
[ "$c1" = 1 ] || { echo "unknown property: exit $c1, expected 1"; exit 1; }
[ "$c2" = 2 ] || { echo "bad size: exit $c2, expected 2"; exit 1; }
[ "$c3" = 1 ] || { echo "missing file: exit $c3, expected 1"; exit 1; }
if ls -A "$T" | grep -q bad; then echo "a failed run left a file behind: $(ls -A "$T")"; exit 1; fi
echo "render workflow: ok"
