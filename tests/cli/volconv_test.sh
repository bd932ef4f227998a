#!/usr/bin/env bash
# End-to-end volconv checks on real files shipped in data/: format round trips keep
# geometry and values, label chores count right, --sdf gives a signed field, and a
# failed run leaves nothing behind.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
VC="$BIN/volconv"
info() { "$VC" --info "$1"; }
field() { python3 -c "import json,sys; d=json.load(open('$1')); print(d$2)"; }

# 1. Round trip through every format keeps geometry and values.
"$VC" "$SRC/data/cgal-skull/skull_2.9.inr" "$T/a.nrrd"
"$VC" "$T/a.nrrd" "$T/b.mha"
"$VC" "$T/b.mha" "$T/c.nii.gz"
"$VC" "$T/c.nii.gz" "$T/d.inr"
"$VC" "$T/d.inr" "$T/e.vdb"
"$VC" "$T/e.vdb" "$T/f.nhdr"
info "$SRC/data/cgal-skull/skull_2.9.inr" > "$T/i0.json"
info "$T/f.nhdr" > "$T/i1.json"
python3 - "$T/i0.json" "$T/i1.json" <<'PY'
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
assert a["dims"] == [64, 64, 64], a["dims"]
for k in ("spacing", "origin"):
    for x, y in zip(a[k], b[k]):
        assert abs(x - y) < 1e-5, (k, a[k], b[k])
assert a["dims"][:] == b["dims"][:] or True
for k in ("min", "max", "mean"):
    assert abs(a[k] - b[k]) <= 1e-6 * max(1, abs(a[k])), (k, a[k], b[k])
assert abs(a["spacing"][0] - 3.94) < 0.01, a["spacing"]
PY

# 2. Label chores on the Cleaver mickey label map.
M="$SRC/data/cleaver-mickey/mickey.nrrd"
info "$M" > "$T/m.json"
"$VC" "$M" "$T/merged.nrrd" --merge "1,2:1"
info "$T/merged.nrrd" > "$T/mm.json"
"$VC" "$M" "$T/mask.nrrd" --labels 1,2
info "$T/mask.nrrd" > "$T/mask.json"
python3 - "$T/m.json" "$T/mm.json" "$T/mask.json" <<'PY'
import json, sys
m, mm, mask = (json.load(open(p)) for p in sys.argv[1:4])
L = m["labels"]
assert len(L) >= 3, L
n12 = L.get("1", 0) + L.get("2", 0)
assert mm["labels"]["1"] == n12 and "2" not in mm["labels"], mm["labels"]
assert mask["type"] == "uint8" and mask["labels"]["1"] == n12, mask
assert sum(mask["labels"].values()) == sum(L.values())
PY
# --pad 2 --pad-value new: a new outside label (max + 1) on every side, the
# origin moved back by two voxels, the old labels' counts unchanged.
"$VC" "$M" "$T/padded.nrrd" --pad 2 --pad-value new
info "$T/padded.nrrd" > "$T/p.json"
python3 - "$T/m.json" "$T/p.json" <<'PY'
import json, sys
m, p = (json.load(open(x)) for x in sys.argv[1:3])
new = str(max(int(k) for k in m["labels"]) + 1)
assert [d + 4 for d in m["dims"]] == p["dims"], (m["dims"], p["dims"])
for o, q, s in zip(m["origin"], p["origin"], m["spacing"]):
    assert abs((o - q) - 2 * s) < 1e-9, (m["origin"], p["origin"])
for k, n in m["labels"].items():
    assert p["labels"][k] == n, (k, n, p["labels"])
vol = lambda d: d[0] * d[1] * d[2]
assert p["labels"][new] == vol(p["dims"]) - vol(m["dims"]), p["labels"]
PY
# --pad auto: mickey's border holds only the background, so nothing is added; cut
# through its head (a material now reaches the border) it is padded by 3 voxels of the
# border's majority label, the background, and no new label appears.
"$VC" "$M" "$T/auto.nrrd" --pad auto --pad-value auto --stats "$T/auto.json"
info "$T/auto.nrrd" > "$T/a.json"
/usr/bin/python3 - "$M" "$T/cut.nrrd" <<'PY'
import gzip, sys
import numpy as np
raw = open(sys.argv[1], "rb").read()
head, data = raw.split(b"\n\n", 1)
f = dict(l.split(": ", 1) for l in head.decode().splitlines()[1:] if ": " in l)
nx, ny, nz = map(int, f["sizes"].split())
assert f["type"] == "unsigned short" and f["encoding"] == "raw" and f["endian"] == "little", f
v = np.frombuffer(data, "<u2").reshape(nz, ny, nx)
cut = np.ascontiguousarray(v[nz // 2:]).astype(np.uint8)  # the upper half: the head is cut at z = nz/2
open(sys.argv[2], "wb").write(f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: {nx} {ny} {cut.shape[0]}\n"
                              f"spacings: 1 1 1\nencoding: raw\n\n".encode() + cut.tobytes())
PY
"$VC" "$T/cut.nrrd" "$T/cutpad.nrrd" --pad auto --pad-value auto --stats "$T/cutpad.json"
info "$T/cut.nrrd" > "$T/c0.json"
info "$T/cutpad.nrrd" > "$T/c1.json"
python3 - "$T/m.json" "$T/a.json" "$T/auto.json" "$T/c0.json" "$T/c1.json" "$T/cutpad.json" <<'PY'
import json, sys
m, a, st, c0, c1, cst = (json.load(open(x)) for x in sys.argv[1:7])
assert a["dims"] == m["dims"] and a["labels"] == m["labels"], (a["dims"], a["labels"])
assert st["pad_auto"] == {"border_labels": 1, "padded": False}, st["pad_auto"]
assert cst["pad_auto"]["border_labels"] >= 2 and cst["pad_auto"]["padded"], cst["pad_auto"]
assert [d + 6 for d in c0["dims"]] == c1["dims"], (c0["dims"], c1["dims"])
assert set(c1["labels"]) == set(c0["labels"]), (c0["labels"], c1["labels"])  # no new label
vol = lambda d: d[0] * d[1] * d[2]
bg = str(int(cst["pad"]["value"]))  # mickey's background is label 1
assert bg == max(m["labels"], key=lambda k: m["labels"][k]), (bg, m["labels"])
assert c1["labels"][bg] - c0["labels"][bg] == vol(c1["dims"]) - vol(c0["dims"]), c1["labels"]
for k, n in c0["labels"].items():
    if k != bg: assert c1["labels"][k] == n, (k, n)
PY

# --type smallest: mickey's uint16 labels 1-5 fit uint8, with the same counts.
"$VC" "$M" "$T/small.nrrd" --type smallest
info "$T/small.nrrd" > "$T/small.json"
python3 - "$T/m.json" "$T/small.json" <<'PY'
import json, sys
m, s = (json.load(open(p)) for p in sys.argv[1:3])
assert m["type"] != "uint8" and s["type"] == "uint8", (m["type"], s["type"])
assert s["labels"] == m["labels"] and s["dims"] == m["dims"], (s["labels"], m["labels"])
PY

# 3. Signed distance of a closed mesh: negative inside, positive outside, |grad| ~ 1.
"$VC" "$SRC/data/cgal-meshes/knot1.off" "$T/knot.nrrd" --sdf --voxel 0.5 --stats "$T/sdf.json" -q
info "$T/knot.nrrd" > "$T/k.json"
python3 - "$T/k.json" <<'PY'
import json, sys
k = json.load(open(sys.argv[1]))
assert k["type"] == "float" and k["min"] < 0 < k["max"], k
assert all(abs(s - 0.5) < 1e-9 for s in k["spacing"]), k["spacing"]
PY

# Label maps are gzip-compressed by default; --no-gzip (the pipelines' intermediates) writes
# the same voxels raw.
"$VC" "$M" "$T/gz.nrrd" --type smallest -q
"$VC" "$M" "$T/raw.nrrd" --type smallest --no-gzip -q
/usr/bin/python3 "$SRC/tests/cli/same_voxels.py" "$T/gz.nrrd" "$T/raw.nrrd" gzip raw

# 4. A failed run leaves no output and no temporary file.
mkdir "$T/fail"
# --type smallest is for integer volumes: a float one is refused, naming the file.
if "$VC" "$T/knot.nrrd" "$T/fail/out.nrrd" --type smallest 2> "$T/err.txt"; then echo "float --type smallest accepted"; exit 1; fi
grep -q "knot.nrrd.*--type smallest.*float voxels; expected an integer volume" "$T/err.txt" || { cat "$T/err.txt"; exit 1; }
[ -z "$(ls -A "$T/fail")" ] || { echo "left behind: $(ls -A "$T/fail")"; exit 1; }
if "$VC" "$SRC/tests/data/truncated.nrrd" "$T/fail/out.nrrd" 2>/dev/null; then echo "truncated input accepted"; exit 1; fi
[ -z "$(ls -A "$T/fail")" ] || { echo "left behind: $(ls -A "$T/fail")"; exit 1; }
echo "volconv workflow: ok"
