#!/usr/bin/env python3
"""Chapter 7 results: volume meshes. Runs `make -f Makefile.pipeline tets` (one material) or
`materials-tets` (label maps) on the shared data, then meshes the same volumes with CGAL Mesh_3
(`baseline cgal|cgal-labels --tets`: cell radius-edge 2, sliver perturbation and exudation) and with
TetGen alone on our own surface (`tetlabel` with no interior points, TetGen -q/-O, with -a searched
so the vertex count matches), all at about our vertex count. Measures every mesh with `meshstats`,
renders cut views, and writes docs/results/ch7.md (+ ch7.json, img/ch7_*.png). Every number comes
from the tools' JSON.

  scripts/results_ch7.py                          # every data set found
  scripts/results_ch7.py --datasets mickey,head   # some of them
  scripts/results_ch7.py --reuse                  # keep finished pipeline runs in the work folder
"""
import argparse
import datetime
import glob
import json
import os
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared", "data"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import results_ch6  # noqa: E402  (data set definitions and the nested head)

CH6 = {name: (src, mvars, desc) for name, src, mvars, desc in results_ch6.DATASETS}

# name, kind (surface: `tets`; materials: `materials-tets`), input, make variables, description
DATASETS = [
    ("brain", "surface", "iso2mesh-head/derived/brain.nrrd", {}, "iso2mesh brain mask, 256^3, 1 mm (one material)"),
    ("skull", "surface", "cgal-skull/skull_2.9.inr", {"ISO": "2.9"}, "CGAL skull, 64^3 grey levels, isovalue 2.9"),
    ("ct-bone", "surface", "vtk-headsq/derived/headsq_quarter.nrrd", {"ISO": "1150", "TIGHTEN": "1",
                                                                     "MIN_COMPONENT": "20"},
     "VTK headsq CT bone at 1150 (quarter resolution), thresholded, cleaned and tightened"),
    ("colin27", "surface", "mricron-ch2bet/ch2bet.nii.gz", {"ISO": "25", "TIGHTEN": "1", "MIN_COMPONENT": "1000"},
     "Colin27 brain-extracted T1 MRI (ch2bet), 181x217x181, 1 mm, isovalue 25, cleaned and tightened"),
    ("bunny", "surface", "sdf:0.006:cgal-meshes/bunny00.off", {"ISO": "0"},
     "signed distance of the bunny, voxel 0.006 (band 8 voxels)"),
    ("knot", "surface", "sdf:0.006:cgal-meshes/knot1.off", {"ISO": "0"},
     "signed distance of knot1, voxel 0.006 (band 8 voxels)"),
    ("armadillo", "surface", "sdf:0.8:cgal-meshes/armadillo.off", {"ISO": "0"},
     "signed distance of the armadillo, voxel 0.8 (band 8 voxels)"),
    ("mickey", "materials") + CH6["mickey"],
    ("spheres", "materials") + CH6["spheres"],
    ("frog5", "materials") + CH6["frog5"],
    ("head", "materials") + CH6["head"],
    ("frog15", "materials") + CH6["frog15"],
]

TARGETS = ("dihedral angles in [12°, 160°], >= 99% of tetrahedra with all six in [25°, 140°], radius ratio "
           "mean >= 0.80, every tetrahedron positive, the boundary the improved surface")

SURFACE_STAGES = ["volconv", "argmax", "morph", "tighten", "medialaxis", "medialaxis_*", "sizingfield", "gradlimit", "mcinit",
                  "particles", "multiparticles", "tetlabel"]
VOLUME_STAGES = ["gradlimit_volume", "particles_volume", "tets"]


def log(msg):
    print(f"results_ch7: {msg}", file=sys.stderr, flush=True)


# One way to run a tool and read its JSON, shared with Chapter 6's script.
run = results_ch6.run
load = results_ch6.load


def run_label(args):
    """Today's date and the commit the tools were built from (--commit, else this checkout's HEAD)."""
    commit = args.commit
    if not commit:
        try:
            commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                                    text=True, check=True).stdout.strip()
        except (OSError, subprocess.CalledProcessError):
            commit = "?"
    return f"{datetime.date.today().isoformat()} ({commit})"


def seconds(out, stages):
    """Each stage's --stats total; a stage "name_*" sums its files (the per-material medial axes) as "name"."""
    s = {}
    for st in stages:
        paths = sorted(glob.glob(os.path.join(out, "work", f"{st}.json")))
        if paths:
            s[st.rstrip("_*")] = round(sum(load(p).get("seconds", {}).get("total", 0.0) for p in paths), 1)
    return s


def summary(q, secs):
    """The columns of one mesh from meshstats' tetrahedral JSON."""
    o = q["overall"]
    return {"vertices": q["vertices"], "tets": o["tets"], "dihedral_min": o["dihedral_min"],
            "dihedral_max": o["dihedral_max"], "share_25_140": o["share_25_140"], "rr_min": o["rr_min"],
            "rr_mean": o["rr_mean"], "share_under_10": o["share_under_10"], "positive": q["positive"],
            "boundary_manifold": q["boundary_manifold"], "triangles_match": q.get("triangles_match"),
            "materials": len(q["materials"]), "seconds": secs}


def meets(s):
    return (s["dihedral_min"] >= 12 and s["dihedral_max"] <= 160 and s["share_25_140"] >= 0.99
            and s["rr_mean"] >= 0.80 and s["positive"])


def measure(args, mesh, qpath):
    run([os.path.join(args.bin, "meshstats"), mesh, "-q", "-o", qpath])
    return load(qpath)


def render(args, mesh, png):
    run([os.path.join(args.bin, "render"), mesh, "-o", png, "--clip", "x", "--legend", "--edges",
         "--size", "900x900", "-q"], ok=(0, 1))


def field_args(out):
    """The field the surface pipeline sampled: its signed distance (masks), else the input at ISO."""
    tl = load(os.path.join(out, "work", "tetlabel.json"))
    p = tl.get("parameters", {})
    sdf = os.path.join(out, "work", "sdf.nrrd")
    if os.path.exists(sdf):
        return ["-i", sdf, "--iso", "0"]
    return ["-i", tl["inputs"][-1], "--iso", str(p["iso"])]


def tetgen_alone(args, out, kind, target, our_volume, our_tets):
    """TetGen -q/-O on our surface with no interior points, -a searched for the vertex count."""
    empty = os.path.join(out, "work", "no_points.ply")
    with open(empty, "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
                "end_header\n")
    tl = load(os.path.join(out, "work", "tets.json"))
    surf = os.path.join(out, "surface.ply" if kind == "surface" else "interfaces.ply")
    base = [os.path.join(args.bin, "tetlabel"), empty, "--conform", surf, "--smooth", "0", "-q"]
    if kind == "surface":
        base += field_args(out)
    else:
        base += ["--materials", tl["parameters"]["materials"]]
    mesh = os.path.join(out, "tetgen_volume.mesh")
    v = 1.5 * our_volume / our_tets  # a first guess: tetrahedra about as large as ours on average
    best = None
    tries = []
    for _ in range(4):
        st = os.path.join(out, "work", "tetgen_volume.json")
        _, secs = run(base + ["--tets", mesh, "--max-volume", f"{v:.6g}", "--stats", st])
        n = load(st)["counts"]["vertices"]
        tries.append({"max_volume": v, "vertices": n, "seconds": round(secs, 1)})
        err = abs(n / target - 1)
        if best is None or err < best[0]:
            best = (err, v, secs)
            shutil.copyfile(mesh, mesh + ".best")
        if err <= 0.1:
            break
        v *= n / target  # N ~ 1 / volume
    os.replace(mesh + ".best", mesh)
    return mesh, best[1], round(best[2], 1), tries


def dataset(args, name, kind, src, mvars, desc, img):
    mesh_src = src.split(":", 2)[2] if src.startswith("sdf:") else None  # "sdf:VOXEL:mesh": its signed distance
    probe = os.path.join(SHARED, {"nested": "iso2mesh-head", "spheres": "cleaver-spheres"}.get(src, mesh_src or src))
    if not os.path.exists(probe):
        log(f"{name}: {probe} not present, skipped")
        return None
    out = os.path.join(args.work, name)
    if not args.reuse and os.path.isdir(out):
        shutil.rmtree(out)
    os.makedirs(out, exist_ok=True)
    if mesh_src:
        inp = os.path.join(args.work, f"{name}_sdf.nrrd")
        if not os.path.exists(inp):
            log(f"{name}: signed distance of {mesh_src}")
            run([os.path.join(args.bin, "volconv"), probe, inp, "--sdf", "--voxel", src.split(":")[1], "--band", "8",
                 "-q"])
    elif kind == "materials":
        inp = results_ch6.ch6_input(name, src, out)
    else:
        inp = os.path.join(SHARED, src)
    target = "tets" if kind == "surface" else "materials-tets"
    cmd = ["make", "-s", "-f", os.path.join(ROOT, "Makefile.pipeline"), target, f"INPUT={inp}", f"OUT={out}",
           f"BIN={args.bin}", "QUIET=1", "TETS=mesh vtu"] + [f"{k}={v}" for k, v in mvars.items()]
    log(f"{name}: {' '.join(cmd[3:])}")
    run(cmd)
    q = load(os.path.join(out, "volume_quality.json"))
    tl = load(os.path.join(out, "work", "tets.json"))
    surf_s, vol_s = seconds(out, SURFACE_STAGES), seconds(out, VOLUME_STAGES)
    row = {"name": name, "kind": kind, "description": desc, "make": mvars,
           "surface_seconds": round(sum(surf_s.values()), 1), "volume_seconds": round(sum(vol_s.values()), 1),
           "stages": {**surf_s, **vol_s}, "ours": summary(q, round(sum(vol_s.values()), 1)),
           "steps": [{"name": s["name"], "vertices": s["vertices"], "seconds": round(s["seconds"], 2),
                      "dihedral_min": s["quality"]["overall"]["dihedral_min"],
                      "dihedral_max": s["quality"]["overall"]["dihedral_max"],
                      "share_25_140": s["quality"]["share_25_140"], "rr_mean": s["quality"]["overall"]["rr_mean"]}
                     for s in tl["steps"]],
           "interior_points": tl["counts"]["interior_kept"], "run": run_label(args)}
    shutil.copyfile(os.path.join(out, "volume.png"), os.path.join(img, f"ch7_{name}_ours.png"))
    n = q["vertices"]
    # CGAL Mesh_3 on the same input at our vertex count.
    try:
        cj = os.path.join(out, "cgal_volume.json")
        cm = os.path.join(out, "cgal_volume.mesh")
        if kind == "surface":
            bl = ["cgal"] + field_args(out)
        else:
            bl = ["cgal-labels", "-i", os.path.join(out, "work", "morph.nrrd")]
        cq = os.path.join(out, "cgal_volume_quality.json")
        if args.reuse and os.path.exists(cq) and os.path.exists(cj):
            log(f"{name}: CGAL Mesh_3 kept from the last run")
            cs = load(cj)
            row["cgal"] = summary(load(cq), round(cs["seconds_final_run"], 1))
        else:
            log(f"{name}: CGAL Mesh_3 at {n} vertices")
            _, secs = run([os.path.join(args.bin, "baseline")] + bl + ["--vertices", str(n), "--tets", cm, "-q",
                                                                        "--stats", cj])
            cs = load(cj)
            row["cgal"] = summary(measure(args, cm, cq), round(cs["seconds_final_run"], 1))
        row["cgal_steps"] = [{"name": s["name"], "vertices": s["vertices"], "seconds": round(s["seconds"], 2),
                              "dihedral_min": s["quality"]["overall"]["dihedral_min"],
                              "dihedral_max": s["quality"]["overall"]["dihedral_max"],
                              "share_25_140": s["quality"]["share_25_140"],
                              "rr_mean": s["quality"]["overall"]["rr_mean"]} for s in cs.get("steps", [])]
        render(args, cm, os.path.join(img, f"ch7_{name}_cgal.png"))
    except (RuntimeError, KeyError) as e:
        row["cgal"] = None
        row["cgal_note"] = f"failed: {str(e).splitlines()[0][:200]}"
        log(f"{name}: CGAL {row['cgal_note']}")
    # TetGen alone on our surface.
    try:
        tq = os.path.join(out, "tetgen_volume_quality.json")
        tr = os.path.join(out, "work", "tetgen_tries.json")
        if args.reuse and os.path.exists(tq) and os.path.exists(tr):
            log(f"{name}: TetGen alone kept from the last run")
            t = load(tr)
            row["tetgen"] = summary(load(tq), t["seconds"])
        else:
            log(f"{name}: TetGen alone at {n} vertices")
            tm, maxv, secs, tries = tetgen_alone(args, out, kind, n, q["overall"]["volume"], q["overall"]["tets"])
            row["tetgen"] = summary(measure(args, tm, tq), secs)
            t = {"max_volume": maxv, "seconds": secs, "tries": tries}
            with open(tr, "w") as f:
                json.dump(t, f)
        row["tetgen"]["max_volume"] = t["max_volume"]
        row["tetgen_tries"] = t["tries"]
    except (RuntimeError, KeyError) as e:
        row["tetgen"] = None
        row["tetgen_note"] = f"failed: {str(e).splitlines()[0][:200]}"
        log(f"{name}: TetGen {row['tetgen_note']}")
    return row


def f1(x):
    return f"{x:.1f}"


def cells(s):
    return (f"{s['vertices']} | {s['tets']} | {f1(s['dihedral_min'])} | {f1(s['dihedral_max'])} | "
            f"{100 * s['share_25_140']:.2f} | {s['rr_min']:.3f} | {s['rr_mean']:.3f} | "
            f"{100 * s['share_under_10']:.3f} | {'yes' if s['positive'] else 'NO'} | "
            f"{'yes' if meets(s) else 'no'} | {s['seconds']}")


def write(docs, rows, failures):
    with open(os.path.join(docs, "ch7.json.tmp"), "w") as f:
        json.dump(rows, f, indent=1)
    os.replace(os.path.join(docs, "ch7.json.tmp"), os.path.join(docs, "ch7.json"))
    L = ["## Chapter 7: tetrahedral volume meshes", "",
         "`make -f Makefile.pipeline tets` (one material) or `materials-tets` (label maps): the surface or "
         "interface pipeline, then the interior sizing (`gradlimit --inward`, VDELTA 0.2), particles packed "
         "inside every material (`particles --volume`, the surface vertices fixed), and the conforming "
         "tetrahedra (`tetlabel --conform`: TetGen's constrained Delaunay of the surface triangles plus the "
         "interior particles, -q refinement at 18°, -O sliver removal at 140°, ODT smoothing and sliver "
         "perturbation of the interior vertices, then, only when tetrahedra outside [12°, 160°] are left, "
         "removal of interior points of the tetrahedra TetGen left outside and one meshing again, the better "
         "kept). Side by side at about the same vertex count: CGAL Mesh_3 on the same volume "
         "(`baseline cgal` on the signed distance, or `cgal-labels` on the cleaned label map; facet angle 30, "
         "cell radius-edge 2, then `perturb_mesh_3` and `exude_mesh_3`), and TetGen alone on our own "
         "surface (no interior points; -q and -O as above, with the volume bound -a searched so the vertex "
         "count matches). Quality by `meshstats` on each file. Targets: " + TARGETS + ".", "",
         "| data | mesher | vertices | tetrahedra | dihedral min (°) | max (°) | % in [25°, 140°] | rr min | "
         "rr mean | % < 10° | positive | targets | time (s) |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        L.append(f"| {r['name']} | ours | {cells(r['ours'])} |")
        if r.get("cgal"):
            L.append(f"| | CGAL Mesh_3 | {cells(r['cgal'])} |")
        else:
            L.append(f"| | CGAL Mesh_3 | {r.get('cgal_note', 'not run')} |||||||||||")
        if r.get("tetgen"):
            L.append(f"| | TetGen alone | {cells(r['tetgen'])} |")
        else:
            L.append(f"| | TetGen alone | {r.get('tetgen_note', 'not run')} |||||||||||")
    L += ["", "Time: ours is interior sizing + packing + tetrahedralisation (the tools' own `--stats` seconds); "
          "CGAL's is its final Mesh_3 run (refinement, perturbation, exudation) without the runs of the "
          "facet-size search; TetGen alone is its final run. The issue's time target compares our volume "
          "stages with our own surface pipeline on the same input:", "",
          "| data | surface pipeline (s) | volume stages (s) | ratio (target <= 2) | interior particles | run (code) |",
          "|---|---|---|---|---|---|"]
    for r in rows:
        ratio = r["volume_seconds"] / r["surface_seconds"] if r["surface_seconds"] else float("nan")
        L.append(f"| {r['name']} | {r['surface_seconds']} | {r['volume_seconds']} | {ratio:.2f} | "
                 f"{r['interior_points']} | {r.get('run', 'before 2026-12-02')} |")
    L += ["", "Each step of the volume meshing, measured (ours, then CGAL's):", ""]
    for r in rows:
        L.append(f"* **{r['name']}** ({r['description']}): " + "; ".join(
            f"{s['name']} {f1(s['dihedral_min'])}..{f1(s['dihedral_max'])}° "
            f"{100 * s['share_25_140']:.1f}% rr {s['rr_mean']:.3f}" for s in r["steps"]))
        if r.get("cgal_steps"):
            L.append("  CGAL: " + "; ".join(
                f"{s['name']} {f1(s['dihedral_min'])}..{f1(s['dihedral_max'])}° "
                f"{100 * s['share_25_140']:.1f}% rr {s['rr_mean']:.3f} ({s['seconds']} s)"
                for s in r["cgal_steps"]))
    for name, err in failures:
        L.append(f"* **{name}**: FAILED: `{err}`")
    L.append("")
    for r in rows:
        L += [f"**{r['name']}**: a cut at the middle plane x = const, tetrahedra crossing it shown whole and "
              "coloured by material: ours" + (", CGAL Mesh_3" if r.get("cgal") else "") + ".", "",
              f"![{r['name']} ours](img/ch7_{r['name']}_ours.png)"
              + (f" ![{r['name']} CGAL](img/ch7_{r['name']}_cgal.png)" if r.get("cgal") else ""), ""]
    with open(os.path.join(docs, "ch7.md.tmp"), "w") as f:
        f.write("\n".join(L) + "\n")
    os.replace(os.path.join(docs, "ch7.md.tmp"), os.path.join(docs, "ch7.md"))
    log(f"wrote {os.path.join(docs, 'ch7.md')}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"))
    ap.add_argument("--datasets", default="", help="comma-separated names (default: all found)")
    ap.add_argument("--work", default=os.path.join(ROOT, "out", "results-ch7"))
    ap.add_argument("--reuse", action="store_true", help="keep finished pipeline runs in --work")
    ap.add_argument("--commit", default="", help="the commit the tools in --bin were built from (default: HEAD)")
    ap.add_argument("--markdown-only", action="store_true", help="rewrite ch7.md from ch7.json, run nothing")
    args = ap.parse_args()
    args.bin = os.path.abspath(args.bin)
    docs = os.path.join(ROOT, "docs", "results")
    if args.markdown_only:
        write(docs, load(os.path.join(docs, "ch7.json")), [])
        return 0
    img = os.path.join(docs, "img")
    os.makedirs(img, exist_ok=True)
    want = set(filter(None, args.datasets.split(",")))
    rows, failures = [], []
    for name, kind, src, mvars, desc in DATASETS:
        if want and name not in want:
            continue
        try:
            r = dataset(args, name, kind, src, mvars, desc, img)
        except RuntimeError as e:
            log(f"{name}: FAILED: {e}")
            failures.append((name, str(e).splitlines()[-1][:300]))
            continue
        if r:
            rows.append(r)
            log(f"{name}: done")
    if want and os.path.exists(os.path.join(docs, "ch7.json")):
        old = {r["name"]: r for r in load(os.path.join(docs, "ch7.json"))}
        new = {r["name"]: r for r in rows}
        rows = [new.get(n) or old[n] for n, *_ in DATASETS if n in new or n in old]
    write(docs, rows, failures)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
