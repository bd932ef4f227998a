#!/usr/bin/env python3
"""Chapter 5 results: for each data set run the ch5 pipeline (Makefile.pipeline),
marching cubes and CGAL Mesh_3 at the same vertex count on the same field,
measure all three with meshstats, render them, and write docs/results/ch5.md
(+ docs/results/ch5.json and docs/results/img/*.png). Nothing in the output is
typed by hand: every number comes from the tools' JSON.

  scripts/results_ch5.py                        # every data set found in ../shared/data
  scripts/results_ch5.py --datasets brain,knot  # some of them
  scripts/results_ch5.py --reuse                # keep finished pipeline runs in the work folder
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared", "data"))

# name, source (relative to SHARED), kind, make variables, description.
# kind "mask": a two-valued volume; "grey": needs ISO; "sdf:<voxel>": a closed
# mesh turned into a signed distance volume first (volconv --sdf).
DATASETS = [
    ("head", "iso2mesh-head/derived/head.nrrd", "mask", {"MIN_COMPONENT": "1000"},
     "iso2mesh head mask, 256^3, 1 mm; components and cavities below 1000 voxels (1 ml) dropped"),
    ("brain", "iso2mesh-head/derived/brain.nrrd", "mask", {}, "iso2mesh brain mask, 256^3, 1 mm"),
    ("ct-bone", "vtk-headsq/derived/headsq_quarter.nrrd", "grey", {"ISO": "1150", "TIGHTEN": "1", "MIN_COMPONENT": "20"},
     "VTK headsq CT (quarter resolution, 64x64x93), bone at 1150, thresholded, cleaned (components below "
     "20 voxels) and tightened: the raw isosurface has sub-voxel bone plates and noise"),
    ("skull", "cgal-skull/skull_2.9.inr", "grey", {"ISO": "2.9"}, "CGAL skull, 64^3 grey levels, isovalue 2.9"),
    ("colin27", "mricron-ch2bet/ch2bet.nii.gz", "grey", {"ISO": "25", "TIGHTEN": "1", "MIN_COMPONENT": "1000"},
     "Colin27 brain-extracted T1 MRI (ch2bet), 181x217x181, 1 mm, isovalue 25, thresholded, cleaned "
     "(components below 1000 voxels) and tightened"),
    ("bunny", "cgal-meshes/bunny00.off", "sdf:0.006", {"ISO": "0"}, "signed distance of the bunny, voxel 0.006 (band 8 voxels)"),
    ("armadillo", "cgal-meshes/armadillo.off", "sdf:0.8", {"ISO": "0"},
     "signed distance of the armadillo, voxel 0.8 (band 8 voxels)"),
    ("knot", "cgal-meshes/knot1.off", "sdf:0.006", {"ISO": "0"}, "signed distance of knot1, voxel 0.006 (band 8 voxels)"),
]

TARGETS = "radius ratio min >= 0.30 and mean >= 0.94; valence 6 >= 65%, < 5 or > 7 <= 1%; edge <= 2h for >= 99.99%"


def log(msg):
    print(f"results_ch5: {msg}", file=sys.stderr, flush=True)


def run(cmd, **kw):
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, **kw)
    dt = time.perf_counter() - t
    if p.returncode not in (0, 3):  # 3: meshstats --require failed, still a report
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr.strip()[-800:]}")
    return p, dt


def load(path):
    with open(path) as f:
        return json.load(f)


def pipeline(args, name, src, kind, mvars, work):
    out = os.path.join(work, name)
    inp = os.path.join(SHARED, src)
    if kind.startswith("sdf:"):
        os.makedirs(work, exist_ok=True)
        sdf = os.path.join(work, f"{name}_sdf.nrrd")
        if not os.path.exists(sdf):
            log(f"{name}: signed distance of {src}")
            run([os.path.join(args.bin, "volconv"), inp, sdf, "--sdf", "--voxel", kind[4:], "--band", "8", "-q"])
        inp = sdf
    reused = args.reuse and os.path.exists(os.path.join(out, "quality.json"))
    if not args.reuse and os.path.isdir(out):
        shutil.rmtree(out)
    cmd = ["make", "-s", "-f", os.path.join(ROOT, "Makefile.pipeline"), "surface", f"INPUT={inp}", f"OUT={out}",
           f"BIN={args.bin}", f"THREADS={args.threads}", "QUIET=1"]
    cmd += [f"{k}={v}" for k, v in mvars.items()] + args.make_vars
    log(f"{name}: surface pipeline -> {out}")
    _, wall = run(cmd)
    return inp, out, None if reused else wall


# Stages of the pipeline whose --stats JSON gives their time.
STAGES = ["morph", "tighten", "medialaxis", "sizingfield", "gradlimit", "mcinit", "particles", "tetlabel"]


def stage_seconds(out):
    secs = {}
    for s in STAGES:
        p = os.path.join(out, "work", f"{s}.json")
        if os.path.exists(p):
            secs[s] = load(p)["seconds"]["total"]
    return secs


def field_of(out, inp, mvars):
    sdf = os.path.join(out, "work", "sdf.nrrd")
    if os.path.exists(sdf):
        return sdf, "0"
    return inp, mvars["ISO"]


def quality(args, mesh, field, iso, sizing, qpath):
    cmd = [os.path.join(args.bin, "meshstats"), mesh, "-i", field, "--iso", iso, "-o", qpath, "-q"]
    if sizing:
        cmd += ["--sizing", sizing]
    run(cmd)
    return load(qpath)


def render(args, mesh, png):
    run([os.path.join(args.bin, "render"), mesh, "-o", png, "--edges", "--size", "480x360", "-q"])


def fresh(args, path, out):
    """With --reuse: `path` exists and is newer than the pipeline's surface (no rerun needed)."""
    surf = os.path.join(out, "surface.ply")
    return args.reuse and os.path.exists(path) and os.path.getmtime(path) >= os.path.getmtime(surf)


def dataset(args, ds, work, imgdir):
    name, src, kind, mvars, desc = ds
    inp, out, wall = pipeline(args, name, src, kind, mvars, work)
    field, iso = field_of(out, inp, mvars)
    sizing = os.path.join(out, "work", "h.nrrd")
    sizing = sizing if os.path.exists(sizing) else None
    ours = load(os.path.join(out, "quality.json"))
    secs = stage_seconds(out)
    rows = [dict(method="particles (ch5)", seconds=sum(secs.values()), q=ours, stages=secs)]
    # The same particles meshed without --improve: the 2008 method's surface.
    plain = os.path.join(out, "surface_delaunay.ply")
    if not fresh(args, plain, out):
        run([os.path.join(args.bin, "tetlabel"), os.path.join(out, "points.ply"), "-i", field, "--iso", iso,
             "-o", plain, "--improve", "0", "-q"])
    rows.append(dict(method="particles, plain Delaunay (no --improve)", seconds=None, q=quality(
        args, plain, field, iso, sizing, os.path.join(out, "delaunay_quality.json"))))
    n = ours["vertices"]
    bl = os.path.join(args.bin, "baseline")
    log(f"{name}: marching cubes")
    mc_stats = os.path.join(out, "mc.json")
    if not fresh(args, mc_stats, out):
        run([bl, "mc", "-i", field, "--iso", iso, "-o", os.path.join(out, "mc.ply"), "--stats", mc_stats, "-q",
             "--threads", str(args.threads)])
    rows.append(dict(method="marching cubes (OpenVDB)", seconds=load(mc_stats)["seconds"]["total"],
                     q=quality(args, os.path.join(out, "mc.ply"), field, iso, sizing,
                               os.path.join(out, "mc_quality.json"))))
    log(f"{name}: CGAL Mesh_3 at about {n} vertices")
    cg_stats = os.path.join(out, "cgal.json")
    if not fresh(args, cg_stats, out):
        run([bl, "cgal", "-i", field, "--iso", iso, "--vertices", str(n), "-o", os.path.join(out, "cgal.ply"),
             "--stats", cg_stats, "-q", "--threads", str(args.threads)])
    cg = load(cg_stats)
    rows.append(dict(method="CGAL Mesh_3", seconds=cg["seconds_final_run"], q=quality(
        args, os.path.join(out, "cgal.ply"), field, iso, sizing, os.path.join(out, "cgal_quality.json")),
        facet_size=cg["parameters"].get("facet_size"), search_runs=len(cg.get("size_search", []))))
    imgs = {}
    for key, mesh in (("ours", "surface.ply"), ("mc", "mc.ply"), ("cgal", "cgal.ply")):
        png = os.path.join(imgdir, f"{name}_{key}.png")
        render(args, os.path.join(out, mesh), png)
        imgs[key] = os.path.relpath(png, os.path.join(ROOT, "docs", "results"))
    return dict(name=name, source=src, description=desc, field=os.path.basename(field), iso=iso,
                pipeline_wall_seconds=wall, rows=rows, images=imgs,
                make_vars=dict(mvars, **dict(v.split("=", 1) for v in args.make_vars)))


def yes(b):
    return "yes" if b else "**no**"


def measures(q):
    """Flat view of a meshstats report."""
    t = q["topology"]
    return dict(
        vertices=q["vertices"], rr_min=q["radius_ratio"]["min"], rr_mean=q["radius_ratio"]["mean"],
        v6=q["valence"]["share_6"], v57=q["valence"]["share_below_5_or_above_7"],
        e2h=q["edge_over_h"]["share_le_2"] if "edge_over_h" in q else None,
        dmean=q["distance_to_surface"]["vertex_mean"] if "distance_to_surface" in q else None,
        dmax=q["distance_to_surface"]["centroid_max"] if "distance_to_surface" in q else None,
        watertight=t["watertight"], manifold=t["manifold"], si=q.get("self_intersecting_pairs"),
        genus=t["genus"], components=t["components"], crease=q.get("crease_share_20"))


def crease(m):
    """crease_share_20 in %, or '-' for reports made before meshstats had it."""
    return "-" if m["crease"] is None else f"{100 * m['crease']:.2f}"


def fmt_row(r):
    m = measures(r["q"])
    e2h = "-" if m["e2h"] is None else f"{100 * m['e2h']:.3f}"
    dist = "-" if m["dmean"] is None else f"{m['dmean']:.3g} / {m['dmax']:.3g}"
    secs = "-" if r["seconds"] is None else f"{r['seconds']:.1f}"
    return (f"| {r['method']} | {secs} | {m['vertices']} | {m['rr_min']:.3f} | {m['rr_mean']:.3f} | "
            f"{100 * m['v6']:.1f} | {100 * m['v57']:.2f} | {crease(m)} | {e2h} | {dist} | "
            f"{yes(m['watertight'])} | {yes(m['manifold'])} | {'-' if m['si'] is None else m['si']} | "
            f"{m['genus']} ({m['components']}) |")


def meets(q, genus):
    m = measures(q)
    checks = {
        "watertight": m["watertight"],
        "manifold": m["manifold"],
        "no self-intersections": m["si"] == 0,
        f"genus {genus} (marching cubes of the same field)": m["genus"] == genus,
        "rr min >= 0.30": m["rr_min"] >= 0.30,
        "rr mean >= 0.94": m["rr_mean"] >= 0.94,
        "valence 6 >= 65%": m["v6"] >= 0.65,
        "valence <5 or >7 <= 1%": m["v57"] <= 0.01,
    }
    if m["e2h"] is not None:
        checks["edge <= 2h for >= 99.99%"] = m["e2h"] >= 0.9999
    return checks


def write_markdown(results, path, args):
    L = ["## Chapter 5: particle meshes against marching cubes and CGAL Mesh_3", "",
         "Generated by `scripts/results_ch5.py` (via `scripts/results`); every number below comes from the "
         "tools' JSON output. Per data set: the `surface` pipeline (formerly `ch5`) of `Makefile.pipeline` (morphology, tightening, "
         "medial axis, sizing field, gradient limiting, marching-cubes seeds, particles, `tetlabel`), then "
         "`baseline mc` (OpenVDB marching cubes, adaptivity 0) and `baseline cgal` (CGAL Mesh_3, facet angle "
         "30, facet distance = size/4, facet size searched to match our vertex count) on the same field, all "
         "measured by `meshstats`.", "",
         f"Targets (issue 5): every mesh water-tight, manifold, free of self-intersections, with the genus of the "
         f"input; {TARGETS}.", "",
         "Columns: time in seconds (ours: sum of the pipeline stages' `--stats` totals; CGAL: the final Mesh_3 "
         "run, without the size search), vertices, radius ratio 2r_in/r_circ min and mean, share of valence-6 "
         "vertices and of valences < 5 or > 7, share of interior edges whose two triangles bend by more than 20 "
         "degrees (`crease_share_20`: slice terraces and noise, which the radius ratio does not see; '-': "
         "a row measured before meshstats reported it), share of edges no longer than 2h (h: our sizing field), distance "
         "to the isosurface (mean at vertices / max at triangle centroids, world units), water-tight, manifold, "
         "self-intersecting triangle pairs, genus (components).", "",
         f"Machine: {os.cpu_count()} cores, `--threads {args.threads}` (0 = all).", ""]
    summary = ["| data set | vertices | rr min | rr mean | valence 6 % | creases > 20° % | targets met |",
               "|---|---|---|---|---|---|---|"]
    for res in results:
        if "error" in res:
            summary.append(f"| {res['name']} | - | - | - | - | - | run failed: {res['error'][:120]} |")
            continue
        q = res["rows"][0]["q"]
        m = measures(q)
        genus = measures(res["rows"][1]["q"])["genus"]
        missed = [k for k, ok in meets(q, genus).items() if not ok]
        summary.append(f"| {res['name']} | {m['vertices']} | {m['rr_min']:.3f} | {m['rr_mean']:.3f} | "
                       f"{100 * m['v6']:.1f} | {crease(m)} | {'all' if not missed else 'missed: ' + ', '.join(missed)} |")
    L += ["### Summary (our meshes)", ""] + summary + [""]
    for res in results:
        L += [f"### {res['name']}", ""]
        if "error" in res:
            L += [f"Run failed: `{res['error']}`", ""]
            continue
        mv = " ".join(f"{k}={v}" for k, v in res["make_vars"].items())
        L += [f"{res['description']} (`{res['source']}`); field `{res['field']}` at iso {res['iso']}"
              + (f"; make variables `{mv}`" if mv else "") + ".", "",
              "| method | time s | vertices | rr min | rr mean | valence 6 % | <5 or >7 % | creases > 20° % | "
              "edge <= 2h % | distance mean / max | watertight | manifold | self-int. | genus |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        L += [fmt_row(r) for r in res["rows"]]
        st = res["rows"][0]["stages"]
        L += ["", "Pipeline stages (s): " + ", ".join(f"{k} {v:.1f}" for k, v in st.items()) +
              (f"; whole `make surface` run including meshstats and renders: {res['pipeline_wall_seconds']:.1f} s."
               if res["pipeline_wall_seconds"] is not None else
               " (pipeline outputs reused from an earlier run: the stage times are that run's).")]
        cg = next(r for r in res["rows"] if r["method"] == "CGAL Mesh_3")
        L += [f"CGAL facet size {cg['facet_size']:.4g} after {cg['search_runs']} Mesh_3 run(s).", ""]
        im = res["images"]
        L += ["| particles (ch5) | marching cubes | CGAL Mesh_3 |", "|---|---|---|",
              f"| ![ours]({im['ours']}) | ![mc]({im['mc']}) | ![cgal]({im['cgal']}) |", ""]
    with open(path + ".tmp", "w") as f:
        f.write("\n".join(L) + "\n")
    os.replace(path + ".tmp", path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"))
    ap.add_argument("--work", default=os.path.join(ROOT, "out", "results"))
    ap.add_argument("--docs", default=os.path.join(ROOT, "docs", "results"))
    ap.add_argument("--datasets", default="", help="comma-separated names (default: all present)")
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--reuse", action="store_true", help="keep finished pipeline outputs in the work folder")
    ap.add_argument("--markdown-only", action="store_true", help="rewrite ch5.md from ch5.json, run nothing")
    ap.add_argument("make_vars", nargs="*", help="extra VAR=value for every make run (e.g. PTOL=1e-4)")
    args = ap.parse_args()
    args.bin = os.path.abspath(args.bin)
    if args.markdown_only:
        write_markdown(load(os.path.join(args.docs, "ch5.json")), os.path.join(args.docs, "ch5.md"), args)
        return
    names = [d[0] for d in DATASETS]
    wanted = args.datasets.split(",") if args.datasets else names
    for w in wanted:
        if w not in names:
            sys.exit(f"results_ch5: unknown data set {w!r}; expected one of {', '.join(names)}")
    imgdir = os.path.join(args.docs, "img")
    os.makedirs(imgdir, exist_ok=True)
    results = []
    for ds in DATASETS:
        if ds[0] not in wanted:
            continue
        if not os.path.exists(os.path.join(SHARED, ds[1])):
            log(f"{ds[0]}: {ds[1]} not in {SHARED}: skipped")
            continue
        try:
            results.append(dataset(args, ds, os.path.abspath(args.work), imgdir))
        except Exception as e:  # report the failure in the table and go on
            log(f"{ds[0]}: FAILED: {e}")
            results.append(dict(name=ds[0], error=str(e)[-400:]))
    if args.datasets and os.path.exists(os.path.join(args.docs, "ch5.json")):
        # A partial run keeps the other data sets' rows from the last full run.
        done = {r["name"] for r in results}
        old = {r["name"]: r for r in load(os.path.join(args.docs, "ch5.json")) if r["name"] not in done}
        new = {r["name"]: r for r in results}
        results = [new.get(n) or old[n] for n in names if n in new or n in old]
    with open(os.path.join(args.docs, "ch5.json"), "w") as f:
        json.dump(results, f, indent=1)
    write_markdown(results, os.path.join(args.docs, "ch5.md"), args)
    log(f"wrote {os.path.relpath(os.path.join(args.docs, 'ch5.md'), ROOT)}")


if __name__ == "__main__":
    main()
