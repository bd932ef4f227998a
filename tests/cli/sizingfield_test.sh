#!/usr/bin/env bash
# End-to-end sizingfield checks on the tightened box fixture and its medial
# axis: the band of known nodes, h = 2 eps min(LFS, 1/k) / g, the options, the
# minimum over several surfaces, gradlimit downstream, and failed runs leaving
# nothing behind.
set -euo pipefail
BIN=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
SZ="$BIN/sizingfield"; VC="$BIN/volconv"; GL="$BIN/gradlimit"; D="$SRC/tests/data"
S="--sdf $D/box_sdf.nrrd --ma $D/box_ma.ply"

"$SZ" $S -o "$T/h.nrrd" --lfs "$T/l.nrrd" --stats "$T/h.json" -q
"$SZ" $S -o "$T/n.nrrd" --no-contract --stats "$T/n.json" -q
"$SZ" $S -o "$T/m.nrrd" --hmin 0.5 --band 2 --stats "$T/m.json" -q
"$SZ" $S $S -o "$T/two.nrrd" --stats "$T/two.json" -q
"$VC" --info "$T/h.nrrd" > "$T/hi.json"
"$VC" --info "$T/l.nrrd" > "$T/li.json"
python3 - "$T/h.json" "$T/n.json" "$T/m.json" "$T/two.json" "$T/hi.json" "$T/li.json" <<'PY'
import json, sys
h, n, m, two, hi, li = (json.load(open(p)) for p in sys.argv[1:7])
c = h["counts"]
assert hi["type"] == "float" and hi["dims"] == [14, 14, 14] and hi["min"] == 0, hi   # 0 = unknown outside the band
assert 0 < c["known"] < 14 ** 3, c
assert 0 < c["h_min"] <= c["h_max"] <= 2 * 0.5 * c["lfs_max"] / 1.5 + 1e-6, c
assert 0.5 < c["lfs_max"] <= 1.6 and abs(li["max"] - c["lfs_max"]) < 1e-6, (c, li)   # box half-width 1.5
assert abs(n["counts"]["h_max"] - 1.5 * c["h_max"]) < 1e-5, (n["counts"], c)        # contraction g = 1.5
assert m["counts"]["h_min"] >= 0.5 and m["counts"]["known"] < c["known"], m["counts"]
assert two["counts"] == c, (two["counts"], c)   # minimum of identical surfaces
PY

# Gradient limiting downstream fills the unknown nodes with positive sizes.
if [ -x "$GL" ]; then
  "$GL" "$T/h.nrrd" "$T/g.nrrd" --delta 0.3 -q
  "$VC" --info "$T/g.nrrd" > "$T/gi.json"
  python3 -c "import json,sys; g=json.load(open(sys.argv[1])); assert g['min'] > 0, g" "$T/gi.json"
fi

# A float field is written raw by default (as tighten and gradlimit write theirs); --gzip
# compresses the same values, the --lfs volume too.
"$SZ" $S -o "$T/h_raw.nrrd" --lfs "$T/l_raw.nrrd" -q
"$SZ" $S -o "$T/h_gz.nrrd" --lfs "$T/l_gz.nrrd" --gzip -q
/usr/bin/python3 "$SRC/tests/cli/same_voxels.py" "$T/h_raw.nrrd" "$T/h_gz.nrrd" raw gzip
/usr/bin/python3 "$SRC/tests/cli/same_voxels.py" "$T/l_raw.nrrd" "$T/l_gz.nrrd" raw gzip

# Failed runs leave no output and no temporary file.
mkdir "$T/fail"
if "$SZ" $S -o "$T/fail/h.nrrd" --eps 0 2>/dev/null; then echo "eps 0 accepted"; exit 1; fi
if "$SZ" --sdf "$D/box_sdf.nrrd" --ma "$D/empty.ply" -o "$T/fail/h.nrrd" 2>/dev/null; then echo "empty MA accepted"; exit 1; fi
if "$SZ" $S -o "$T/fail/h.nrrd" --lfs "$T/fail/l.xyz" 2>/dev/null; then echo "bad --lfs accepted"; exit 1; fi
[ -z "$(ls -A "$T/fail")" ] || { echo "left behind: $(ls -A "$T/fail")"; exit 1; }
echo "sizingfield workflow: ok"
