#!/usr/bin/env python3
"""Cohort sheet, per-scan outcome and cohort report of the workflow (workflow/Snakefile).

    cohort.py check SHEET                      validate a sheet (what the Snakefile does first)
    cohort.py outcome --id ID --pipeline P --input F --scan-dir DIR -o outcome.json
    cohort.py report --results DIR --csv report.csv --html report.html OUTCOME.json...

The sheet is a CSV with the columns id, input, pipeline (surface | materials) and optional
columns named after make variables of Makefile.pipeline (surface) or Makefile.ch6
(materials), e.g. ISO, LABELS, R, EPS, DELTA, SPACING, MERGE; an empty cell keeps the
default. Relative inputs are relative to the sheet's folder. Lines starting with '#' and
blank lines are ignored.
"""
import argparse
import base64
import csv
import html
import json
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pmstage import DEFAULTS, STAGES  # noqa: E402

REQUIRED = ("id", "input", "pipeline")
ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
# variables whose value must be a number (the others are strings: label lists, ops, flags)
NUMERIC = {"ISO", "R", "EPS", "DELTA", "SPACING", "UPSAMPLE", "PTOL", "IMPROVE", "DECIMATE", "HMIN",
           "MIN_COMPONENT", "MIN_VOXELS", "PAD", "DOWNSAMPLE", "TIGHTEN_BAND"}
# ... of which these may also be "auto", as in the makefiles
AUTO = {"R", "UPSAMPLE", "HMIN", "PAD", "TIGHTEN_BAND"}


class SheetError(Exception):
    pass


def read_sheet(path):
    """Rows of a cohort sheet as dicts {id, input (absolute), pipeline, vars{NAME: value}}.

    Raises SheetError with one line naming the sheet, the row (its line number) and what was
    expected, for a missing column, an unknown column, a duplicated or malformed id, an unknown
    pipeline, an override that is not a number where one is needed, and an input that does
    not exist or cannot be read.
    """
    where = f'cohort sheet "{path}"'
    try:
        f = open(path, newline="")
    except OSError as e:
        raise SheetError(f"{where}: cannot be read: {e.strerror}")
    base = os.path.dirname(os.path.abspath(path))
    with f:
        lines = [(n, l) for n, l in enumerate(f, start=1) if l.strip() and not l.lstrip().startswith("#")]
    if not lines:
        raise SheetError(f"{where}: empty; expected a header row id,input,pipeline[,VARIABLE...]")
    rows = list(csv.reader([l for _, l in lines]))
    header = [h.strip() for h in rows[0]]
    hline = lines[0][0]
    for col in REQUIRED:
        if col not in header:
            raise SheetError(f'{where}: row {hline} (header): missing column "{col}"; expected the columns '
                             f"id,input,pipeline[,VARIABLE...], got {','.join(header)}")
    known = set(DEFAULTS["surface"]) | set(DEFAULTS["materials"])
    for col in header:
        if col not in REQUIRED and col not in known:
            raise SheetError(f'{where}: row {hline} (header): unknown column "{col}"; expected id, input, '
                             f"pipeline or a make variable: {', '.join(sorted(known))}")
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise SheetError(f'{where}: row {hline} (header): column "{dup}" appears twice')
    scans, seen = [], {}
    for (n, _), fields in zip(lines[1:], rows[1:]):
        at = f"{where}: row {n}"
        if len(fields) != len(header):
            raise SheetError(f"{at}: {len(fields)} fields; expected {len(header)} ({','.join(header)})")
        r = {h: v.strip() for h, v in zip(header, fields)}
        sid, inp, pipe = r["id"], r["input"], r["pipeline"]
        if not ID_RE.match(sid):
            raise SheetError(f'{at}: id "{sid}": expected letters, digits, ".", "_" or "-" (it names a folder)')
        if sid in seen:
            raise SheetError(f'{at}: id "{sid}" duplicates row {seen[sid]}; expected unique ids')
        seen[sid] = n
        if pipe not in DEFAULTS:
            raise SheetError(f'{at}: pipeline "{pipe}"; expected surface or materials')
        if not inp:
            raise SheetError(f"{at}: empty input; expected a volume file")
        full = inp if os.path.isabs(inp) else os.path.join(base, inp)
        if not os.path.isfile(full):
            raise SheetError(f'{at}: input "{inp}": no such file')
        try:
            with open(full, "rb") as g:
                g.read(1)
        except OSError as e:
            raise SheetError(f'{at}: input "{inp}" cannot be read: {e.strerror}')
        overrides = {}
        for k, val in r.items():
            if k in REQUIRED or val == "":
                continue
            if k not in DEFAULTS[pipe]:
                raise SheetError(f'{at}: {k}={val}: {k} is not a variable of the {pipe} pipeline; expected one of '
                                 f"{', '.join(DEFAULTS[pipe])}")
            if k in NUMERIC and not (k in AUTO and val == "auto"):
                try:
                    float(val)
                except ValueError:
                    raise SheetError(f'{at}: {k}="{val}": expected a number' + (" or auto" if k in AUTO else ""))
            overrides[k] = val
        scans.append({"id": sid, "input": os.path.normpath(full), "pipeline": pipe, "vars": overrides, "row": n})
    if not scans:
        raise SheetError(f"{where}: no scans; expected one row per scan after the header")
    return scans


# --- per-scan outcome -----------------------------------------------------------------

def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def read_benchmark(path):
    """Snakemake's benchmark TSV: {seconds, max_rss_mib} (None where Snakemake wrote NA)."""
    try:
        with open(path) as f:
            head, vals = f.read().splitlines()[:2]
    except (OSError, ValueError):
        return None
    d = dict(zip(head.split("\t"), vals.split("\t")))

    def num(k):
        try:
            return float(d.get(k))
        except (TypeError, ValueError):
            return None
    return {"seconds": num("s"), "max_rss_mib": num("max_rss")}


def quality_summary(q, pipeline):
    """The figures of meshstats' JSON the report shows (overall for materials)."""
    if not q:
        return {}
    o = q.get("overall", q) if pipeline == "materials" else q
    t = o.get("topology", {})
    s = {
        "vertices": o.get("vertices"), "faces": o.get("faces"),
        "watertight": t.get("watertight"), "manifold": t.get("manifold"),
        "components": t.get("components"), "genus": t.get("genus"),
        "rr_min": o.get("radius_ratio", {}).get("min"), "rr_mean": o.get("radius_ratio", {}).get("mean"),
        "angle_min_deg": o.get("angle_deg", {}).get("min"),
        "valence6": o.get("valence", {}).get("share_6"),
        "self_intersections": o.get("self_intersecting_pairs"),
    }
    if pipeline == "materials":  # interfaces water-tight, every material closed and manifold
        i = q.get("interfaces", {})
        s["materials"] = len(q.get("materials", {}) or {})
        s["watertight"] = bool(i.get("watertight")) and bool(i.get("materials_closed"))
        s["manifold"] = i.get("materials_manifold")
        s["rr_min"] = i.get("rr_min_over_materials", s["rr_min"])
        s["self_intersections"] = sum(m.get("self_intersecting_pairs") or 0 for m in q.get("materials", {}).values())
    return s


def outcome(sid, pipeline, inp, scan_dir):
    stages, failed = [], None
    for stage in STAGES[pipeline]:
        st = read_json(os.path.join(scan_dir, "work", stage, "status.json")) or {"status": "missing"}
        bench = read_benchmark(os.path.join(scan_dir, "benchmarks", f"{stage}.tsv")) or {}
        stages.append({"stage": stage, "status": st.get("status"), "seconds": st.get("seconds"),
                       "peak_rss_mib": st.get("peak_rss_mib"), "bench_max_rss_mib": bench.get("max_rss_mib"),
                       "bench_seconds": bench.get("seconds"), "threads": st.get("threads"),
                       "error": st.get("error"), "note": st.get("note")})
        if failed is None and st.get("status") in ("failed", "missing"):
            failed = stages[-1]
    q = read_json(os.path.join(scan_dir, "work", "meshstats", "quality.json"))
    ok = failed is None
    peaks = [(s["peak_rss_mib"] or 0, s["stage"]) for s in stages]
    peak = max(peaks) if peaks else (0, None)
    return {
        "id": sid, "pipeline": pipeline, "input": inp, "status": "ok" if ok else "failed",
        "failed_stage": None if ok else failed["stage"],
        "error": None if ok else (failed.get("error") or "stage did not run (see its log)"),
        "log": None if ok else os.path.join(scan_dir, "logs", f"{failed['stage']}.log"),
        "seconds": round(sum(s["seconds"] or 0 for s in stages), 2),
        "peak_rss_mib": peak[0] or None, "peak_stage": peak[1] if peak[0] else None,
        "quality": quality_summary(q, pipeline),
        "thumbnail": os.path.join(scan_dir, "work", "render", "thumb.png"),
        "stages": stages,
    }


# --- cohort report ------------------------------------------------------------------

QUALITY_COLS = ["vertices", "faces", "watertight", "manifold", "components", "genus", "rr_min", "rr_mean",
                "angle_min_deg", "valence6", "self_intersections", "materials"]


def fmt(v, digits=3):
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{digits}g}" if abs(v) < 1e4 else f"{v:.0f}"
    return str(v)


def write_report(outcomes, csv_path, html_path):
    all_stages = []
    for o in outcomes:
        for s in o["stages"]:
            if s["stage"] not in all_stages:
                all_stages.append(s["stage"])
    cols = (["id", "pipeline", "input", "status", "failed_stage", "error", "seconds", "peak_rss_mib", "peak_stage"]
            + QUALITY_COLS + [f"{s}_{k}" for s in all_stages for k in ("seconds", "peak_rss_mib", "bench_max_rss_mib")])
    tmp = csv_path + ".tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for o in outcomes:
            row = {k: o.get(k) for k in cols[:9]}
            row.update(o["quality"])
            for s in o["stages"]:
                for k in ("seconds", "peak_rss_mib", "bench_max_rss_mib"):
                    row[f"{s['stage']}_{k}"] = s[k]
            w.writerow(["" if row.get(c) is None else (str(row[c]).lower() if isinstance(row[c], bool) else row[c])
                        for c in cols])
    os.replace(tmp, csv_path)

    ok = [o for o in outcomes if o["status"] == "ok"]
    bad = [o for o in outcomes if o["status"] != "ok"]
    e = html.escape
    h = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>particlemesh cohort report</title><style>",
         "body{font-family:sans-serif;margin:1.5em;color:#222}table{border-collapse:collapse;margin:.5em 0}",
         "td,th{border:1px solid #ccc;padding:3px 7px;text-align:right;font-size:90%}th{background:#eee}",
         "td.l{text-align:left}.bad{color:#b00}.ok{color:#070}img{display:block}details{margin:.2em 0}",
         "</style></head><body>",
         f"<h1>particlemesh cohort report</h1><p>{len(outcomes)} scans: {len(ok)} meshed, "
         f"<span class='bad'>{len(bad)} failed</span>. Times are wall-clock seconds of each stage; peak "
         "memory is the tool's resident high-water mark (kernel, MiB), with Snakemake's sampled "
         "benchmark max_rss beside it. Figures from meshstats (overall for multi-material scans).</p>"]
    if bad:
        h.append("<h2>Failed scans</h2><table><tr><th>id</th><th>pipeline</th><th>stage</th><th>error</th>"
                 "<th>log</th></tr>")
        for o in bad:
            h.append(f"<tr><td class='l'>{e(o['id'])}</td><td class='l'>{e(o['pipeline'])}</td>"
                     f"<td class='l'>{e(o['failed_stage'] or '')}</td><td class='l bad'>{e(o['error'] or '')}</td>"
                     f"<td class='l'>{e(o['log'] or '')}</td></tr>")
        h.append("</table>")
    h.append("<h2>Scans</h2><table><tr><th>render</th><th>id</th><th>status</th>"
             + "".join(f"<th>{c}</th>" for c in QUALITY_COLS) + "<th>seconds</th><th>peak MiB (stage)</th></tr>")
    for o in outcomes:
        img = ""
        try:
            with open(o["thumbnail"], "rb") as f:
                img = f"<img alt='{e(o['id'])}' src='data:image/png;base64,{base64.b64encode(f.read()).decode()}'>"
        except OSError:
            pass
        cls = "ok" if o["status"] == "ok" else "bad"
        q = o["quality"]
        h.append(f"<tr><td>{img}</td><td class='l'>{e(o['id'])}<br><small>{e(o['pipeline'])}</small></td>"
                 f"<td class='l {cls}'>{e(o['status'])}</td>"
                 + "".join(f"<td>{e(fmt(q.get(c)))}</td>" for c in QUALITY_COLS)
                 + f"<td>{fmt(o['seconds'])}</td><td>{fmt(o['peak_rss_mib'])} ({e(o['peak_stage'] or '')})</td></tr>")
    h.append("</table><h2>Stages</h2>")
    for o in outcomes:
        h.append(f"<details><summary>{e(o['id'])}: {e(o['status'])}, {fmt(o['seconds'])} s</summary>"
                 "<table><tr><th>stage</th><th>status</th><th>seconds</th><th>peak MiB</th>"
                 "<th>benchmark max_rss MiB</th><th>threads</th><th>note / error</th></tr>")
        for s in o["stages"]:
            h.append(f"<tr><td class='l'>{e(s['stage'])}</td><td class='l'>{e(s['status'] or '')}</td>"
                     f"<td>{fmt(s['seconds'])}</td><td>{fmt(s['peak_rss_mib'])}</td><td>{fmt(s['bench_max_rss_mib'])}</td>"
                     f"<td>{fmt(s['threads'])}</td><td class='l'>{e(s['error'] or s['note'] or '')}</td></tr>")
        h.append("</table></details>")
    h.append("</body></html>\n")
    tmp = html_path + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(h))
    os.replace(tmp, html_path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("check")
    c.add_argument("sheet")
    o = sub.add_parser("outcome")
    for k in ("--id", "--pipeline", "--input", "--scan-dir", "-o"):
        o.add_argument(k, required=True)
    r = sub.add_parser("report")
    r.add_argument("--csv", required=True)
    r.add_argument("--html", required=True)
    r.add_argument("outcomes", nargs="+")
    a = ap.parse_args()
    if a.cmd == "check":
        try:
            scans = read_sheet(a.sheet)
        except SheetError as e:
            print(f"cohort: error: {e}", file=sys.stderr)
            return 1
        print(f"cohort: {len(scans)} scans", file=sys.stderr)
    elif a.cmd == "outcome":
        res = outcome(a.id, a.pipeline, a.input, a.scan_dir)
        with open(a.o + ".tmp", "w") as f:
            json.dump(res, f, indent=1)
        os.replace(a.o + ".tmp", a.o)
    else:
        write_report([read_json(p) for p in a.outcomes], a.csv, a.html)
    return 0


if __name__ == "__main__":
    sys.exit(main())
