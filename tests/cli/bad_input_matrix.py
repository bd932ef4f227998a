#!/usr/bin/env python3
"""The bad-input matrix (issue 7): every tool against every kind of bad input.

usage: bad_input_matrix.py BIN_DIR SRC_DIR

Each row runs one tool on one bad input and requires:
  * exit code 1 (bad data, run-time failure) or 2 (usage error), as the row says;
    never a crash (signal, sanitizer abort) or 0;
  * exactly one non-empty line on stderr (run with -q so progress stays quiet),
    of the form "<tool>: error: ..." or "<tool>: usage error: ...", naming the
    offending file or option;
  * nothing left in the output folder (no output, no temporary file).
Then tools that write one or several files are interrupted with SIGINT and
SIGTERM at points the test has observed (PM_TEST_HOLD), and must die of the
signal, say so, and leave the output folder empty.
Prints one line per failing row and a summary line; exit 0 when all pass.
"""
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

BIN, SRC = sys.argv[1], sys.argv[2]
DATA = os.path.join(SRC, "tests", "data")
T = tempfile.mkdtemp(prefix="pm_matrix_")
OUT = os.path.join(T, "out")
os.mkdir(OUT)


def fx(name):
    return os.path.join(T, name)


def write(name, text, mode="w"):
    with open(fx(name), mode) as f:
        f.write(text)
    return fx(name)


def nrrd(name, sizes, values, typ="float"):
    body = " ".join(str(v) for v in values)
    return write(name, "NRRD0004\ntype: %s\ndimension: %d\nsizes: %s\nspacings: %s\nencoding: ascii\n\n%s\n"
                 % (typ, len(sizes), " ".join(map(str, sizes)), " ".join(["0.5"] * len(sizes)), body))


def ply(name, points, count=None):
    head = "ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    return write(name, head % (len(points) if count is None else count) + "".join("%s %s %s\n" % p for p in points))


# --- fixtures ----------------------------------------------------------------
MISSING_V, MISSING_M = fx("missing.nrrd"), fx("missing.ply")
EMPTY_V, EMPTY_M = write("empty.nrrd", ""), write("empty.ply", "")
TRUNC_V = os.path.join(DATA, "truncated.nrrd")
TRUNC_M = ply("truncated.ply", [(0, 0, 0), (1, 0, 0)], count=50)
PLANE = os.path.join(DATA, "plane2d.nrrd")
MASK = os.path.join(DATA, "box_mask.nrrd")      # uint8 labels 0/1
SDF = os.path.join(DATA, "box_sdf.nrrd")        # float signed distance
MA = os.path.join(DATA, "box_ma.ply")
NAN_V = nrrd("nan_inf.nrrd", [3, 3, 3], ["nan" if k == 4 else ("inf" if k == 20 else -1 + 0.1 * k) for k in range(27)])
NAN_M = ply("nan.ply", [(0, 0, 0), (1, 0, 0), ("nan", 1, 0), (0, 0, 1), (1, 1, 1)])
FAR = nrrd("far.nrrd", [4, 4, 4], [2.0 + k * 0.01 for k in range(64)])  # positive everywhere: no surface
EMPTY_MASK = os.path.join(DATA, "empty_mask.nrrd")
ZEROS = os.path.join(DATA, "zeros.nrrd")
NOPTS = os.path.join(DATA, "empty.ply")
SPHERE_PTS = os.path.join(DATA, "sphere_points.ply")
TET = os.path.join(DATA, "tet.off")
UNWRITABLE = os.path.join(T, "no_such_dir", "out")
# World frame (issue 21): NRRD "space" and "space directions" of different dimensions.
SPACE_CONFLICT = os.path.join(DATA, "space_conflict.nrrd")

# --- the tools and how each is called ----------------------------------------
# Each tool: a function (input, output) -> argv for its main input, the kind of
# that input ("volume" or "mesh"), the output's extension, and rows of its own
# (wrong-type volumes, no surface, out-of-range options).
def o(ext):
    return os.path.join(OUT, "result" + ext)


TOOLS = {
    "volconv": dict(kind="volume", ext=".nrrd", argv=lambda i, out: [i, out]),
    "particles": dict(kind="volume", ext=".ply", argv=lambda i, out: ["-i", i, "--iso", "0", "--spacing", "0.5", "-o", out]),
    "render": dict(kind="mesh", ext=".png", argv=lambda i, out: [i, "-o", out]),
    "morph": dict(kind="volume", ext=".nrrd", argv=lambda i, out: [i, out, "--op", "dilate"]),
    "gradlimit": dict(kind="volume", ext=".nrrd", argv=lambda i, out: [i, out]),
    "mcinit": dict(kind="volume", ext=".ply", argv=lambda i, out: [i, out, "--iso", "0"]),
    "tighten": dict(kind="volume", ext=".nrrd", argv=lambda i, out: [i, out, "-r", "0.5"]),
    "medialaxis": dict(kind="volume", ext=".ply", argv=lambda i, out: [i, out]),
    "sizingfield": dict(kind="volume", ext=".nrrd", argv=lambda i, out: ["--sdf", i, "--ma", MA, "-o", out]),
    "tetlabel": dict(kind="mesh", ext=".ply", argv=lambda i, out: [i, "--implicit", "sphere", "-o", out]),
    "meshstats": dict(kind="mesh", ext=".json", argv=lambda i, out: [i, "-o", out]),
    "baseline": dict(kind="volume", ext=".ply", argv=lambda i, out: ["mc", "-i", i, "--iso", "0", "-o", out]),
    "multiparticles": dict(kind="volume", ext=".ply", argv=lambda i, out: ["--materials", i, "--spacing", "0.5", "-o", out]),
    "quadmesh": dict(kind="mesh", ext=".ply", argv=lambda i, out: [i, "-o", out]),
}

# Extra rows: (tool, case, argv, exit code, what the message must name).
P, VOL = "particles", "volume"
EXTRA = [
    ("quadmesh", "STL output (triangles only)", [MISSING_M, "-o", o(".stl")], 2, o(".stl")),
    ("quadmesh", "surface without types", [TET, "-o", o(".ply")], 1, TET),
    ("quadmesh", "--max-fold -1", [TET, "-o", o(".ply"), "--max-fold", "-1"], 2, "--max-fold"),
    ("quadmesh", "--smooth -1", [TET, "-o", o(".ply"), "--smooth", "-1"], 2, "--smooth"),
    ("quadmesh", "--gmsh with --types", [TET, "--gmsh", "--types", TET, "-o", o(".ply")], 2, "--gmsh"),
    ("quadmesh", "smoothing field missing", [TET, "--gmsh", "-i", MISSING_V, "--iso", "0", "-o", o(".ply")], 1,
     MISSING_V),
    # a second input of the mesh tools is a volume (a field) or a point set
    ("tetlabel", "field missing", [SPHERE_PTS, "-i", MISSING_V, "--iso", "0", "-o", o(".ply")], 1, MISSING_V),
    ("tetlabel", "field 2-D", [SPHERE_PTS, "-i", PLANE, "--iso", "0", "-o", o(".ply")], 1, PLANE),
    ("tetlabel", "field NaN/Inf", [SPHERE_PTS, "-i", NAN_V, "--iso", "0", "-o", o(".ply")], 1, NAN_V),
    ("tetlabel", "field no surface", [SPHERE_PTS, "-i", FAR, "--iso", "0", "-o", o(".ply")], 1, FAR),
    ("tetlabel", "too few points", [NOPTS, "--implicit", "sphere", "-o", o(".ply")], 1, NOPTS),
    ("meshstats", "field truncated", [TET, "-i", TRUNC_V, "--iso", "0", "-o", o(".json")], 1, TRUNC_V),
    ("meshstats", "sizing is labels (h = 0)", [TET, "--sizing", MASK, "-o", o(".json")], 1, MASK),
    ("meshstats", "sizing NaN/Inf", [TET, "--sizing", NAN_V, "-o", o(".json")], 1, NAN_V),
    ("meshstats", "point set, no faces", [SPHERE_PTS, "-o", o(".json")], 1, SPHERE_PTS),
    ("render", "no points", [NOPTS, "-o", o(".png")], 1, NOPTS),
    ("volconv", "mesh input missing", [MISSING_M, o(".nrrd"), "--sdf", "--voxel", "0.1"], 1, MISSING_M),
    ("volconv", "mesh input NaN", [NAN_M, o(".nrrd"), "--sdf", "--voxel", "0.1"], 1, NAN_M),
    ("volconv", "mesh input truncated", [TRUNC_M, o(".nrrd"), "--sdf", "--voxel", "0.1"], 1, TRUNC_M),
    ("volconv", "no surface for --distance", [FAR, o(".nrrd"), "--distance", "0"], 1, FAR),
    # Chapter 4: particles --field on Nektar++ files
    (P, "nektar mesh missing", ["-i", fx("missing.xml"), "--field", fx("missing.fld") + ":u", "--iso", "0.5",
                                "--spacing", "0.1", "-o", o(".ply")], 1, fx("missing.xml")),
    (P, "nektar mesh malformed", ["-i", write("bad_nektar.xml", "<NEKTAR><GEOMETRY DIM=\"3\">"), "--field",
                                  fx("missing.fld") + ":u", "--iso", "0.5", "--spacing", "0.1", "-o", o(".ply")],
     1, fx("bad_nektar.xml")),
    (P, "nektar field without :VARIABLE", ["-i", fx("missing.xml"), "--field", fx("missing.fld"), "--iso", "0.5",
                                           "--spacing", "0.1", "-o", o(".ply")], 2, "--field"),
    (P, "seeds missing", ["--implicit", "sphere", "--spacing", "0.3", "--init", MISSING_M, "-o", o(".ply")], 1, MISSING_M),
    (P, "seeds empty", ["--implicit", "sphere", "--spacing", "0.3", "--init", EMPTY_M, "-o", o(".ply")], 1, EMPTY_M),
    (P, "seeds truncated", ["--implicit", "sphere", "--spacing", "0.3", "--init", TRUNC_M, "-o", o(".ply")], 1, TRUNC_M),
    (P, "seeds NaN", ["--implicit", "sphere", "--spacing", "0.3", "--init", NAN_M, "-o", o(".ply")], 1, "seed point 2"),
    (P, "sizing is labels (h = 0)", ["--implicit", "sphere", "--sizing", MASK, "-o", o(".ply")], 1, MASK),
    (P, "sizing NaN/Inf", ["--implicit", "sphere", "--sizing", NAN_V, "-o", o(".ply")], 1, NAN_V),
    (P, "sizing 2-D", ["--implicit", "sphere", "--sizing", PLANE, "-o", o(".ply")], 1, PLANE),
    (P, "no surface", ["-i", FAR, "--iso", "0", "--spacing", "0.5", "-o", o(".ply")], 1, FAR),
    # a NRRD whose space and space directions disagree in dimension
    ("volconv", "space vs space directions", [SPACE_CONFLICT, o(".nrrd")], 1, SPACE_CONFLICT),
    ("morph", "space vs space directions", [SPACE_CONFLICT, o(".nrrd"), "--op", "dilate"], 1, SPACE_CONFLICT),
    (P, "space vs space directions", ["-i", SPACE_CONFLICT, "--iso", "0.5", "--spacing", "0.5", "-o", o(".ply")], 1,
     SPACE_CONFLICT),
    # wrong-type volumes: labels where a distance field is expected and the reverse
    ("medialaxis", "labels, not a distance field", [MASK, o(".ply")], 1, MASK),
    ("sizingfield", "labels, not a distance field", ["--sdf", MASK, "--ma", MA, "-o", o(".nrrd")], 1, MASK),
    ("sizingfield", "medial axis missing", ["--sdf", SDF, "--ma", MISSING_M, "-o", o(".nrrd")], 1, MISSING_M),
    ("sizingfield", "medial axis truncated", ["--sdf", SDF, "--ma", TRUNC_M, "-o", o(".nrrd")], 1, TRUNC_M),
    ("tighten", "distance field, not a mask", [SDF, o(".nrrd"), "-r", "0.5"], 1, SDF),
    ("morph", "distance field, not labels", [SDF, o(".nrrd"), "--op", "dilate"], 1, SDF),
    ("mcinit", "distance field, not labels (--junctions)", [SDF, o(".ply"), "--junctions"], 1, SDF),
    ("gradlimit", "labels, not a sizing field", [EMPTY_MASK, o(".nrrd")], 1, EMPTY_MASK),
    # no surface
    ("mcinit", "no surface", [FAR, o(".ply"), "--iso", "0"], 1, FAR),
    ("tighten", "empty mask", [EMPTY_MASK, o(".nrrd"), "-r", "0.5"], 1, EMPTY_MASK),
    ("medialaxis", "no surface", [FAR, o(".ply")], 1, FAR),
    ("sizingfield", "no surface", ["--sdf", FAR, "--ma", MA, "-o", o(".nrrd")], 1, FAR),
    ("gradlimit", "no h > 0", [ZEROS, o(".nrrd")], 1, ZEROS),
    # out-of-range options
    ("volconv", "--voxel -1", [TET, o(".nrrd"), "--sdf", "--voxel", "-1"], 2, "--voxel"),
    ("volconv", "--type bogus", [SDF, o(".nrrd"), "--type", "bogus"], 2, "bogus"),
    (P, "--spacing 0", ["--implicit", "sphere", "--spacing", "0", "-o", o(".ply")], 2, "spacing"),
    (P, "--threads -1", ["--implicit", "sphere", "--spacing", "0.3", "--threads", "-1", "-o", o(".ply")], 2, "--threads"),
    ("render", "--size 0x10", [SPHERE_PTS, "-o", o(".png"), "--size", "0x10"], 2, "--size"),
    ("morph", "--iterations 0", [MASK, o(".nrrd"), "--op", "dilate", "--iterations", "0"], 2, "--iterations"),
    ("morph", "--downsample 0", [MASK, o(".nrrd"), "--downsample", "0"], 2, "--downsample"),
    ("gradlimit", "--delta -1", [SDF, o(".nrrd"), "--delta", "-1"], 2, "--delta"),
    ("gradlimit", "--far-field sideways", [SDF, o(".nrrd"), "--far-field", "sideways"], 2, "--far-field"),
    ("mcinit", "--decimate 0", [SDF, o(".ply"), "--iso", "0", "--decimate", "0"], 2, "--decimate"),
    ("tighten", "--radius 0", [MASK, o(".nrrd"), "-r", "0"], 2, "radius"),
    ("tighten", "--outside-band -1", [MASK, o(".nrrd"), "-r", "0.5", "--outside-band", "-1"], 2, "outside-band"),
    ("tighten", "--outside-band wide", [MASK, o(".nrrd"), "-r", "0.5", "--outside-band", "wide"], 2, "outside-band"),
    ("medialaxis", "--cos-alpha 2", [SDF, o(".ply"), "--cos-alpha", "2"], 2, "--cos-alpha"),
    ("sizingfield", "--eps 0", ["--sdf", SDF, "--ma", MA, "-o", o(".nrrd"), "--eps", "0"], 2, "--eps"),
    ("tetlabel", "--inside sideways", [SPHERE_PTS, "--implicit", "sphere", "-o", o(".ply"), "--inside", "sideways"], 2, "--inside"),
    ("meshstats", "--require nonsense", [TET, "--require", "nonsense>=1"], 2, "nonsense"),
    ("baseline", "mode bogus", ["bogus", "-i", SDF, "-o", o(".ply")], 2, "bogus"),
    ("baseline", "no surface", ["mc", "-i", FAR, "--iso", "0", "-o", o(".ply")], 1, FAR),
    ("multiparticles", "--spacing 0", ["--materials", MASK, "--spacing", "0", "-o", o(".ply")], 2, "spacing"),
    ("particles", "--coarse-tolerance -1",
     ["--implicit", "sphere", "--spacing", "0.3", "-o", o(".ply"), "--coarse-tolerance", "-1"], 2, "coarse tolerance"),
    ("particles", "--coarse-population-tolerance -1",
     ["--implicit", "sphere", "--spacing", "0.3", "-o", o(".ply"), "--coarse-population-tolerance", "-1"], 2,
     "coarse population tolerance"),
    ("particles", "--step-factor 1",
     ["--implicit", "sphere", "--spacing", "0.3", "-o", o(".ply"), "--step-factor", "1"], 2, "step factor"),
    ("particles", "--step-control bogus",
     ["--implicit", "sphere", "--spacing", "0.3", "-o", o(".ply"), "--step-control", "bogus"], 2, "step-control"),
    ("multiparticles", "--step-factor 0.5",
     ["--materials", MASK, "--spacing", "1", "-o", o(".ply"), "--step-factor", "0.5"], 2, "step factor"),
    # unsupported extensions of the other outputs and an unknown --frame (issue 21), inputs missing
    ("tetlabel", "--tets .obj", [MISSING_M, "--implicit", "sphere", "-o", o(".ply"), "--tets", o(".obj")], 2, o(".obj")),
    ("tetlabel", "--frame xyz", [MISSING_M, "--implicit", "sphere", "-o", o(".ply"), "--frame", "xyz"], 2, "--frame"),
    ("mcinit", "points as .mesh", [MISSING_V, o(".mesh"), "--iso", "0"], 2, o(".mesh")),
    ("mcinit", "--stats .txt", [MISSING_V, o(".ply"), "--iso", "0", "--stats", o(".txt")], 2, o(".txt")),
    ("medialaxis", "--volume .xyz", [MISSING_V, o(".ply"), "--volume", o(".xyz")], 2, o(".xyz")),
    ("sizingfield", "--lfs .xyz", ["--sdf", MISSING_V, "--ma", MA, "-o", o(".nrrd"), "--lfs", o(".xyz")], 2, o(".xyz")),
]


TIMES = []


def run(tool, argv, timeout=600):  # a hang guard, far above any row's run time even on a loaded machine
    exe = os.path.join(BIN, tool)
    t0 = time.time()
    p = subprocess.run([exe, "-q"] + argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=timeout)
    TIMES.append((time.time() - t0, tool + " " + " ".join(os.path.basename(a) for a in argv)))
    return p.returncode, p.stderr.decode("utf-8", "replace")


failures, count = [], 0
T0 = time.time()
present = [t for t in TOOLS if os.path.exists(os.path.join(BIN, t))]
rows = []
for t in present:
    d = TOOLS[t]
    if d["kind"] == "volume":
        common = [("missing file", MISSING_V, 1), ("empty file", EMPTY_V, 1), ("truncated file", TRUNC_V, 1),
                  ("2-D volume", PLANE, 1), ("NaN/Inf voxels", NAN_V, 1)]
    else:
        common = [("missing file", MISSING_M, 1), ("empty file", EMPTY_M, 1), ("truncated file", TRUNC_M, 1),
                  ("NaN vertex", NAN_M, 1)]
    for case, path, code in common:
        rows.append((t, case, d["argv"](path, o(d["ext"])), code, path))
    good = {"volconv": SDF, "particles": SDF, "render": SPHERE_PTS, "morph": MASK, "gradlimit": SDF, "mcinit": SDF,
            "tighten": MASK, "medialaxis": SDF, "sizingfield": SDF, "tetlabel": SPHERE_PTS, "meshstats": TET,
            "baseline": SDF, "multiparticles": MASK, "quadmesh": os.path.join(DATA, "typed_tet.ply")}[t]
    rows.append((t, "unwritable output", d["argv"](good, UNWRITABLE + d["ext"]), 1, UNWRITABLE + d["ext"]))
    # An output extension the tool cannot write is a usage error found before the
    # (here missing) input is opened: exit 2, not the missing file's exit 1.
    missing = MISSING_V if d["kind"] == "volume" else MISSING_M
    rows.append((t, "unsupported output extension, input missing", d["argv"](missing, o(".xyz")), 2, o(".xyz")))
rows += [r for r in EXTRA if r[0] in present]

for tool, case, argv, code, names in rows:
    count += 1
    try:
        rc, err = run(tool, argv)
    except subprocess.TimeoutExpired:
        failures.append("%s / %s: timed out" % (tool, case))
        continue
    lines = [l for l in err.splitlines() if l.strip()]
    problems = []
    if rc != code:
        problems.append("exit %d, expected %d" % (rc, code))
    if len(lines) != 1:
        problems.append("%d stderr lines, expected 1" % len(lines))
    prefix = "%s: %s" % (tool, "usage error: " if code == 2 else "error: ")
    if not lines or not lines[0].startswith(prefix):
        problems.append("message does not start with %r" % prefix)
    if names not in err:
        problems.append("message does not name %r" % os.path.basename(names))
    left = os.listdir(OUT)
    if left:
        problems.append("left files behind: %s" % " ".join(left))
        for f in left:
            os.remove(os.path.join(OUT, f))
    if problems:
        failures.append("%s / %s: %s\n    stderr: %s" % (tool, case, "; ".join(problems), err.strip()[:400]))

T1 = time.time()
# --- interrupted runs leave nothing ------------------------------------------
# Each run is signalled at a moment the test has seen, not after a guessed
# delay (issue #23): PM_TEST_HOLD=<point> makes the tool print "test hold at
# <point>" on stderr and wait there (libcore/include/pm/base/test_hold.h).
#   stage:<name>  mid-computation, at the start of a named stage;
#   commit        after the work, every output written as a temporary file and
#                 none renamed into place: the moment a careless handler would
#                 leave a half-finished result behind.
# At "commit" the test first checks that the temporary files really are there
# (so it would notice a handler that leaves them), then signals, then requires:
# the run died of the signal, said so on stderr, and left the folder empty.
# Every tool shares the handler of pm::Tool (libcore/src/cli/run_tool.cpp).
SEEDS = fx("wedge_seeds.ply")
if "mcinit" in present:
    subprocess.run([os.path.join(BIN, "mcinit"), "-q", os.path.join(DATA, "wedges3.nrrd"), SEEDS, "--junctions"],
                   check=True)
LONG = [  # tool, argv, hold points, files a whole run writes
    ("volconv", [TET, o(".nrrd"), "--sdf", "--voxel", "0.05"], ["stage:sdf", "commit"], 1),
    ("volconv", [SDF, os.path.join(OUT, "result.nhdr")], ["commit"], 2),  # header + detached data file
    ("particles", ["--implicit", "torus", "--spacing", "0.3", "-o", o(".ply")], ["stage:write", "commit"], 1),
    ("tighten", [MASK, o(".nrrd"), "-r", "0.5"], ["stage:tighten", "commit"], 1),
    # interfaces, the surfaces of materials 2 and 3 (1 is the outside), the tetrahedra
    ("tetlabel", [SEEDS, "--materials", os.path.join(DATA, "wedges3.nrrd"), "-o", o(".ply"),
                  "--material-surfaces", OUT, "--tets", o(".mesh")], ["stage:label", "commit"], 4),
]
HOLD_LIMIT = 600  # seconds a run may take to reach its hold point: a hang guard, not a speed test


def wait_for_hold(p, point):
    """Read stderr until the hold line; return (reached, stderr so far)."""
    lines = []
    done = threading.Event()

    def reader():
        for raw in iter(p.stderr.readline, b""):
            line = raw.decode("utf-8", "replace")
            lines.append(line)
            if "test hold at " + point in line:
                done.set()
                return
        done.set()

    threading.Thread(target=reader, daemon=True).start()
    done.wait(HOLD_LIMIT)
    return any("test hold at " + point in l for l in lines), "".join(lines)


for tool, argv, points, n_out in LONG:
    if tool not in present or (tool == "tetlabel" and not os.path.exists(SEEDS)):
        continue
    # an uninterrupted run writes exactly its outputs
    count += 1
    rc, err = run(tool, argv, timeout=HOLD_LIMIT)
    written = sorted(os.listdir(OUT))
    if rc != 0 or len(written) != n_out or any(f.startswith(".") for f in written):
        failures.append("%s: a whole run exited %d and wrote %s, expected %d outputs\n    stderr: %s"
                        % (tool, rc, " ".join(written) or "nothing", n_out, err.strip()[:400]))
    for f in written:
        os.remove(os.path.join(OUT, f))
    for point in points:
        for sig in (signal.SIGINT, signal.SIGTERM):
            count += 1
            what = "%s / %s at %s" % (tool, sig.name, point)
            env = dict(os.environ, PM_TEST_HOLD=point, PM_TEST_HOLD_SECONDS=str(HOLD_LIMIT))
            p = subprocess.Popen([os.path.join(BIN, tool), "-q"] + argv, stdout=subprocess.DEVNULL,
                                 stderr=subprocess.PIPE, env=env)
            reached, err = wait_for_hold(p, point)
            problems = []
            if not reached:
                p.kill()
                rest = p.communicate()[1].decode("utf-8", "replace")
                failures.append("%s: never reached the hold point (exit %s)\n    stderr: %s"
                                % (what, p.returncode, (err + rest).strip()[:400]))
                for f in os.listdir(OUT):
                    os.remove(os.path.join(OUT, f))
                continue
            held = os.listdir(OUT)
            temps = [f for f in held if f.startswith(".") and ".tmp" in f]
            if point == "commit" and len(temps) != n_out:
                problems.append("at the hold %d temporary files, expected %d (%s)" % (len(temps), n_out, " ".join(held)))
            if len(temps) != len(held):
                problems.append("outputs in place before the end: %s" % " ".join(sorted(set(held) - set(temps))))
            p.send_signal(sig)
            t0 = time.time()
            try:
                _, rest = p.communicate(timeout=HOLD_LIMIT)
            except subprocess.TimeoutExpired:
                p.kill()
                p.communicate()
                failures.append("%s: did not stop" % what)
                continue
            TIMES.append((time.time() - t0, "%s stop after %s at %s" % (tool, sig.name, point)))
            rest = rest.decode("utf-8", "replace")
            if p.returncode != -sig:
                problems.append("exit %s, expected death by %s" % (p.returncode, sig.name))
            if "%s: interrupted by %s" % (tool, sig.name) not in rest:
                problems.append("stderr does not say \"%s: interrupted by %s\"" % (tool, sig.name))
            left = os.listdir(OUT)
            if left:
                problems.append("left %s" % " ".join(left))
            for f in left:
                os.remove(os.path.join(OUT, f))
            if problems:
                failures.append("%s: %s\n    stderr: %s" % (what, "; ".join(problems), rest.strip()[:400]))

shutil.rmtree(T, ignore_errors=True)
if os.environ.get("PM_MATRIX_TIMES"):
    for t, what in sorted(TIMES, reverse=True)[:12]:
        print("%6.2fs  %s" % (t, what))
for f in failures:
    print("FAIL " + f)
print("bad-input matrix: %d rows in %.0f s, interrupted runs in %.0f s; tools: %s"
      % (count, T1 - T0, time.time() - T1, " ".join(present)))
print("%d passed, %d failed" % (count - len(failures), len(failures)))
sys.exit(1 if failures else 0)
