#!/usr/bin/env bash
# The cohort workflow (workflow/Snakefile) end to end with `snakemake --cores 2`: three good
# scans (the Cleaver mickey label map through the materials pipeline, one of its labels as a
# mask through the surface pipeline, a generated ball mask through the surface pipeline) and
# one bad one (a NRRD whose data is cut short). The report must list the three as meshed with
# water-tight, manifold meshes and positive counts, time and peak memory for every stage, and
# the bad one as failed with volconv's error line; a rerun must do nothing. Bad cohort sheets
# (missing column, duplicated id, unreadable input) are refused before any job runs, naming
# the row. Skips (exit 77) when snakemake is not installed.
set -euo pipefail
BIN=$1; SRC=$2
PY=/usr/bin/python3
if ! command -v snakemake >/dev/null 2>&1 || ! $PY -c 'import snakemake' 2>/dev/null; then
  echo "SKIP: snakemake is not installed (Debian package snakemake; scripts/setup installs it)"; exit 77
fi
MICKEY=$SRC/data/cleaver-mickey/mickey.nrrd
test -f "$MICKEY" || { echo "missing $MICKEY" >&2; exit 1; }
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
SMK=(snakemake -s "$SRC/workflow/Snakefile" --directory "$T" --cores 2 --keep-going)

# a ball mask (radius 7 voxels; spacing 0.5 x 0.5 x 0.7, so that R auto, the largest spacing,
# is not the smallest) and a NRRD that promises 24^3 voxels but holds 100
$PY - "$T/ball.nrrd" "$T/truncated.nrrd" <<'PY'
import math, sys
n, c = 24, 11.5
vals = bytes(1 if math.dist((i, j, k), (c, c, c)) <= 7 else 0 for k in range(n) for j in range(n) for i in range(n))
head = f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: {n} {n} {n}\nspacings: 0.5 0.5 0.7\nencoding: raw\n\n".encode()
open(sys.argv[1], "wb").write(head + vals)
open(sys.argv[2], "wb").write(head + vals[:100])
PY

# --- bad sheets: refused up front, naming the row, before any job runs -------------------
# (the Snakefile's own check for one of them; cohort.py check runs the same code for the rest)
refused() {  # refused NAME EXPECTED-REGEX [snakemake]: the sheet $T/NAME.csv must be refused with that message
  if [ "${3:-}" = snakemake ]; then cmd=("${SMK[@]}" --config sheet="$T/$1.csv" results="$T/res_$1" bin="$BIN")
  else cmd=($PY "$SRC/workflow/scripts/cohort.py" check "$T/$1.csv"); fi
  if "${cmd[@]}" > "$T/$1.out" 2>&1; then echo "sheet $1 was accepted" >&2; cat "$T/$1.out" >&2; exit 1; fi
  grep -Eq "$2" "$T/$1.out" || { echo "sheet $1: expected /$2/ in:" >&2; cat "$T/$1.out" >&2; exit 1; }
  test ! -e "$T/res_$1" || { echo "sheet $1: jobs ran" >&2; exit 1; }
}
printf 'id,input,pipeline\nball,ball.nrrd,surface\nmickey,%s,materials\nball,ball.nrrd,surface\n' "$MICKEY" > "$T/dup.csv"
refused dup 'cohort: error: cohort sheet ".*dup.csv": row 4: id "ball" duplicates row 2; expected unique ids' snakemake
printf 'id,input\nball,ball.nrrd\n' > "$T/nocolumn.csv"
refused nocolumn 'cohort: error: cohort sheet ".*nocolumn.csv": row 1 \(header\): missing column "pipeline"'
printf 'id,input,pipeline\nball,ball.nrrd,surface\ngone,nope.nrrd,surface\n' > "$T/missing.csv"
refused missing 'cohort: error: cohort sheet ".*missing.csv": row 3: input "nope.nrrd": no such file'
mkdir "$T/adir.nrrd"
printf 'id,input,pipeline\nball,adir.nrrd,surface\n' > "$T/dir.csv"
refused dir 'row 2: input "adir.nrrd": no such file'
printf 'id,input,pipeline,EPS\nball,ball.nrrd,surface,small\n' > "$T/badvalue.csv"
refused badvalue 'row 2: EPS="small": expected a number'
printf 'id,input,pipeline,MERGE\nball,ball.nrrd,surface,1:2\n' > "$T/wrongvar.csv"
refused wrongvar 'row 2: MERGE=1:2: MERGE is not a variable of the surface pipeline'

# --- the cohort: three good scans and a bad one ------------------------------------------
cat > "$T/cohort.csv" <<EOF
# id,input,pipeline and per-scan overrides of the make variables (empty = default)
id,input,pipeline,LABELS,R,DELTA
mickey,$MICKEY,materials,,,
ear,$MICKEY,surface,3,,
ball,ball.nrrd,surface,,,0.1
cut,truncated.nrrd,surface,,,
EOF
"${SMK[@]}" --config sheet="$T/cohort.csv" results="$T/res" bin="$BIN" > "$T/run1.out" 2>&1 ||
  { echo "first run failed" >&2; tail -40 "$T/run1.out" >&2; exit 1; }
for f in report.csv report.html mickey/work/tetlabel/interfaces.ply ear/work/tetlabel/surface.ply \
         ball/work/particles/particles.json ball/benchmarks/particles.tsv cut/logs/inspect.log; do
  test -s "$T/res/$f" || { echo "missing $f" >&2; tail -40 "$T/run1.out" >&2; exit 1; }
done

$PY - "$T/res" <<'PY'
import csv, json, os, sys
res = sys.argv[1]
rows = {r["id"]: r for r in csv.DictReader(open(os.path.join(res, "report.csv")))}
assert sorted(rows) == ["ball", "cut", "ear", "mickey"], sorted(rows)
for sid in ("mickey", "ear", "ball"):
    r = rows[sid]
    assert r["status"] == "ok", (sid, r["status"], r["error"])
    assert r["watertight"] == "true" and r["manifold"] == "true", (sid, r["watertight"], r["manifold"])
    assert int(r["vertices"]) > 100 and int(r["faces"]) > 2 * int(r["vertices"]) - 10, (sid, r["vertices"], r["faces"])
    # radius ratios lie in (0, 1]; the improved surfaces' mean is well above a random mesh's
    assert 0 < float(r["rr_min"]) <= float(r["rr_mean"]) <= 1 and float(r["rr_mean"]) > 0.8, (sid, r["rr_min"], r["rr_mean"])
    assert r["self_intersections"] == "0", (sid, r["self_intersections"])
    assert float(r["seconds"]) > 0 and float(r["peak_rss_mib"]) > 1, (sid, r["seconds"], r["peak_rss_mib"])
    # every stage that ran a tool has a time and the tool's peak memory
    for stage in ("inspect", "tighten", "tetlabel", "meshstats", "render"):
        assert float(r[f"{stage}_seconds"]) > 0 and float(r[f"{stage}_peak_rss_mib"]) > 1, (sid, stage)
assert rows["mickey"]["materials"] == "5", rows["mickey"]["materials"]
# a ball of radius 7 voxels (an ellipsoid in world units): one component of genus 0
assert rows["ball"]["components"] == "1" and rows["ball"]["genus"] == "0", rows["ball"]
# the per-scan override reached the tool: gradlimit ran with DELTA 0.1 on the ball, 0.05 on the ear
for sid, delta in (("ball", "0.1"), ("ear", "0.05")):
    cmd = json.load(open(os.path.join(res, sid, "work", "gradlimit", "status.json")))["commands"][0]
    assert f"--delta {delta}" in cmd, (sid, cmd)
assert "--labels 3" in json.load(open(os.path.join(res, "ear", "work", "mask", "status.json")))["commands"][0]
cut = rows["cut"]
assert cut["status"] == "failed" and cut["failed_stage"] == "inspect", cut
assert cut["error"].startswith("volconv: error: ") and "truncated.nrrd" in cut["error"], cut["error"]
for stage in ("mask", "particles", "render"):
    st = json.load(open(os.path.join(res, "cut", "work", stage, "status.json")))
    assert st["status"] == "skipped" and st["commands"] == [], (stage, st)
page = open(os.path.join(res, "report.html")).read()
assert page.count("src='data:image/png;base64,") == 3, page.count("data:image/png")
assert "Failed scans" in page and "volconv: error: " in page and "truncated.nrrd" in page
print("report:", {k: (v["status"], v["vertices"], v["rr_mean"], v["seconds"], v["peak_rss_mib"]) for k, v in rows.items()})
PY

# --- the same commands and defaults as the makefiles: the same points and meshes, byte for byte -
for scan in "mickey materials $MICKEY" "ear surface $MICKEY LABELS=3" "ball surface $T/ball.nrrd DELTA=0.1"; do
  set -- $scan
  make -s -j2 -f "$SRC/Makefile.pipeline" "$2" INPUT="$3" ${4:+"$4"} OUT="$T/make_$1" BIN="$BIN" THREADS=2 QUIET=1 \
    2> "$T/make_$1.err" || { echo "make $2 of $1 failed" >&2; cat "$T/make_$1.err" >&2; exit 1; }
  if [ "$2" = materials ]; then pairs="multiparticles/points.ply:points.ply tetlabel/interfaces.ply:interfaces.ply"
  else pairs="particles/points.ply:points.ply tetlabel/surface.ply:surface.ply"; fi
  for p in $pairs; do
    cmp "$T/res/$1/work/${p%%:*}" "$T/make_$1/${p##*:}" ||
      { echo "$1: the cohort's ${p%%:*} differs from make $2's ${p##*:}" >&2; exit 1; }
  done
done

# --- a rerun does nothing ----------------------------------------------------------------
before=$(stat -c %Y "$T/res/report.csv" "$T/res/ball/work/particles/points.ply")
points_mtime=$(stat -c %Y "$T/res/ball/work/particles/points.ply")
"${SMK[@]}" --config sheet="$T/cohort.csv" results="$T/res" bin="$BIN" > "$T/run2.out" 2>&1 ||
  { echo "rerun failed" >&2; cat "$T/run2.out" >&2; exit 1; }
grep -q "Nothing to be done" "$T/run2.out" || { echo "rerun did something:" >&2; cat "$T/run2.out" >&2; exit 1; }
test "$before" = "$(stat -c %Y "$T/res/report.csv" "$T/res/ball/work/particles/points.ply")"

# --- resumable: a deleted stage folder is remade with what follows it, and nothing else.
# Snakemake 7.21 does not rebuild a missing intermediate while the files after it exist,
# so the scan's outcome.json and the report go too (or use --forcerun RULE) ---
rm -rf "$T/res/ball/work/tetlabel" "$T/res/ball/outcome.json" "$T/res/report.csv" "$T/res/report.html"
"${SMK[@]}" --config sheet="$T/cohort.csv" results="$T/res" bin="$BIN" > "$T/run3.out" 2>&1 ||
  { echo "resume failed" >&2; cat "$T/run3.out" >&2; exit 1; }
jobs=$(grep -Eo '^(local)?rule [a-z_]+:' "$T/run3.out" | sed 's/^local//' | grep -v '^rule all:' | sort | tr -d '\n')
test "$jobs" = "rule outcome:rule report:rule surface_meshstats:rule surface_render:rule surface_tetlabel:" ||
  { echo "resume ran: $jobs" >&2; cat "$T/run3.out" >&2; exit 1; }
test "$(stat -c %Y "$T/res/ball/work/particles/points.ply")" = "$points_mtime"

# --- the Slurm profile parses and sets per-stage threads and memory (dry run, no cluster) -
# (--cores 64 so that the dry run does not cap threads at one core as a local run would)
"${SMK[@]}" --profile "$SRC/workflow/profiles/slurm" -n --forceall --cores 64 --config sheet="$T/cohort.csv" \
  results="$T/res" bin="$BIN" > "$T/slurm.out" 2>&1 || { echo "slurm profile dry run failed" >&2; cat "$T/slurm.out" >&2; exit 1; }
$PY - "$T/slurm.out" "$SRC/workflow/profiles/slurm/config.yaml" <<'PY'
import re, sys
out, prof = open(sys.argv[1]).read(), open(sys.argv[2]).read()
want_mem = dict(re.findall(r"- (\w+):mem_mb=(\d+)", prof))
want_thr = dict(re.findall(r"- (\w+)=(\d+)\n", prof))
jobs = re.findall(r"rule (\w+):\n(?:    .*\n)*?    resources: ([^\n]*)", out)
assert len(jobs) >= 20, len(jobs)
for rule, res in jobs:
    if rule in want_mem:
        assert f"mem_mb={want_mem[rule]}," in res + ",", (rule, res, want_mem[rule])
table = dict(re.findall(r"^(\w+)\s+\d+\s+\d+\s+(\d+)$", out, re.M))
for rule, n in want_thr.items():
    if rule in table:
        assert table[rule] == n, (rule, table[rule], n)
assert table.get("surface_particles") == want_thr["surface_particles"], table
PY
echo "workflow passed"
