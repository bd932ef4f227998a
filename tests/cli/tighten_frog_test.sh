#!/usr/bin/env bash
# tighten's convergence on the zero set's mean move (kTightenCycleShare): on frog5's label
# map (the ch6 results' case: 5 merged materials, downsampled 2x to 2 x 2 x 3 mm, closed and
# opened, R = 2 mm) a few nodes of the background's and the skin's zero sets keep moving by
# more than the tolerance every step, so the largest move alone ran both labels to the step
# cap (20 (R/h)^2 + 160 = 180). Their mean move over a re-distancing cycle (25 steps) falls
# below half the tolerance first; the run stops there, converged, and running on to the cap
# moves the zero set by little. Skipped when the shared data is absent.
set -euo pipefail
BIN=$1; SRC=$2
FROG="$SRC/../shared/data/vtk-frogtissue/derived/frogtissue.nrrd"
[ -f "$FROG" ] || { echo "SKIP: $FROG not present"; exit 0; }
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
"$BIN/volconv" "$FROG" "$T/labels.nrrd" --type int32 --merge "13:1 11:2 1,6:3 2,3,4,5,7,8,9,10,12,14,15:4" \
  --min-voxels 300 --pad 3 --pad-value 0 -q
"$BIN/morph" "$T/labels.nrrd" "$T/morph.nrrd" --labels 0,1,2,3,4 --ops close:ball,open:ball --downsample 2 --vote -q
"$BIN/tighten" "$T/morph.nrrd" "$T/s_%d.nrrd" --per-label --radius 2 --threads 2 --stats "$T/t.json" -q
# The same run, on to the step cap (the old rule: only the largest move could stop it).
"$BIN/tighten" "$T/morph.nrrd" "$T/l_%d.nrrd" --per-label --radius 2 --threads 2 --tolerance 1e-9 \
  --iterations 180 --stats "$T/l.json" -q
/usr/bin/python3 - "$T" <<'PY'
import gzip, json, sys
import numpy as np
t = sys.argv[1]
short = json.load(open(f"{t}/t.json"))["counts"]["per_label"]
long_ = json.load(open(f"{t}/l.json"))["counts"]["per_label"]
def read(p):
    raw = open(p, "rb").read()
    head, data = raw.split(b"\n\n", 1)
    f = dict(l.split(": ", 1) for l in head.decode().splitlines()[1:] if ": " in l)
    if f.get("encoding") == "gzip":
        data = gzip.decompress(data)
    nx, ny, nz = map(int, f["sizes"].split())
    return np.frombuffer(data, "<f4").reshape(nz, ny, nx)
bad = []
cycle_stopped = 0
for lab in ("0", "1"):
    s, l = short[lab], long_[lab]
    assert l["iterations"] == 180, (lab, l)
    if not s["converged"]:
        bad.append(f"label {lab}: not converged after {s['iterations']} steps")
        continue
    if s["iterations"] < 180 and s["last_change_voxels"] >= 1e-3:
        # stopped by the cycle rule: at a cycle's end, with the mean below half the tolerance
        cycle_stopped += 1
        if s["iterations"] % 25 or not s["cycle_change_voxels"] < 0.5e-3:
            bad.append(f"label {lab}: stopped at {s['iterations']} with mean move {s['cycle_change_voxels']}")
    a, b = read(f"{t}/s_{lab}.nrrd"), read(f"{t}/l_{lab}.nrrd")
    # Nodes next to the zero set (a face neighbour across it): how much the longer run moved them.
    near = np.zeros(a.shape, bool)
    for ax in range(3):
        d = np.diff(np.signbit(a), axis=ax)
        sl0 = [slice(None)] * 3; sl1 = [slice(None)] * 3
        sl0[ax] = slice(0, -1); sl1[ax] = slice(1, None)
        near[tuple(sl0)] |= d
        near[tuple(sl1)] |= d
    dev = np.abs(a - b)[near] / 2.0  # voxels (h = 2 mm)
    print(f"label {lab}: {s['iterations']} steps (cap 180), mean move over the last cycle "
          f"{s['cycle_change_voxels']:.5f} voxel; the zero set's nodes then move {dev.mean():.4f} voxel "
          f"in the mean (99%: {np.percentile(dev, 99):.3f}) on to the cap")
    # Measured 0.01-0.02 voxel; a tenth of a voxel is far below what the mesh resolves.
    if not dev.mean() < 0.1:
        bad.append(f"label {lab}: the zero set moves {dev.mean():.3f} voxel in the mean after the stop")
# Re-distancing on the share of zero-set nodes whose |grad phi| is off (kReinitShare), not on
# the worst one: 3-5% of the background's are off whatever the field (the surface bends on the
# scale of a voxel), so the worst-node rule re-distanced it every cycle (6 times in 175 steps).
if not short["0"]["reinits"] <= 2:
    bad.append(f"label 0: {short['0']['reinits']} re-distancings (the share rule gives 1 or 2)")
if cycle_stopped == 0:
    bad.append("neither label was stopped by the cycle rule (each ran to the cap or settled node by node)")
if bad:
    sys.exit("FAIL: " + "; ".join(bad))
print("OK")
PY
