#!/usr/bin/env python3
"""Run one stage of one scan of the cohort workflow (workflow/Snakefile).

    pmstage.py PIPELINE STAGE --input VOLUME --work RESULTS/ID/work --bin BIN
               --vars JSON --threads N --log LOG

Each stage writes into its own folder WORK/STAGE: the tool's outputs, its --stats JSON and
status.json (status ok | failed | skipped | not_needed, the commands, exit code, error line,
seconds, peak resident memory of the tool in MiB from the kernel's high-water mark). The
commands and tool parameters are those of Makefile.pipeline / Makefile.ch6, with the same
defaults (DEFAULTS below).

A failing tool does not fail the job: the stage records "failed" with the tool's error
line and exits 0, and every later stage of that scan records "skipped". So `snakemake`
finishes the other scans, the cohort report always runs, and a rerun does nothing; a
failed scan is retried by `--forcerun` of its stage folder or by deleting RESULTS/ID (see
README, "Cohorts"). Only a killed wrapper (e.g. a Slurm time limit) fails the job, which
Snakemake then reruns with --rerun-incomplete.
"""
import argparse
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time

# Make variables of Makefile.pipeline (ch5, "surface") and Makefile.ch6 ("materials") that a
# cohort sheet may override per scan, with the makefiles' defaults ("" = unset).
DEFAULTS = {
    "surface": {
        "ISO": "", "LABELS": "", "STENCIL": "ball", "MIN_COMPONENT": "", "R": "auto",
        "EPS": "0.5", "DELTA": "0.05", "SPACING": "", "UPSAMPLE": "auto", "MORPH": "",
        "TIGHTEN": "", "REQUIRE": "", "FLAGS": "-q", "PTOL": "1e-4", "PFLAGS": "",
        "IMPROVE": "3", "DECIMATE": "4", "HMIN": "",
    },
    "materials": {
        "MERGE": "", "MIN_VOXELS": "0", "PAD": "auto", "PAD_VALUE": "",
        "MORPH_OPS": "close:ball,open:ball", "DOWNSAMPLE": "1", "R": "auto", "UPSAMPLE": "auto",
        "TIGHTEN_BAND": "", "EPS": "0.3", "DELTA": "0.05", "HMIN": "auto", "SPACING": "", "DECIMATE": "1",
        "SAMPLER": "multiparticles", "IMPROVE": "3", "MPFLAGS": "", "REQUIRE": "",
        "FLAGS": "-q", "MA_SIDE": "inside", "KERNEL": "catmull-rom",
    },
}

# Stages in order, and the earlier stages each one reads (its Snakemake inputs).
STAGES = {
    "surface": {
        "inspect": [], "mask": ["inspect"], "morph": ["inspect", "mask"],
        "tighten": ["inspect", "morph"], "medialaxis": ["inspect", "tighten"],
        "sizingfield": ["inspect", "tighten", "medialaxis"],
        "gradlimit": ["inspect", "sizingfield"], "mcinit": ["inspect", "tighten"],
        "particles": ["inspect", "tighten", "gradlimit", "mcinit"],
        "tetlabel": ["inspect", "tighten", "particles"],
        "meshstats": ["inspect", "tighten", "gradlimit", "mcinit", "tetlabel"],
        "render": ["inspect", "particles", "tetlabel"],
    },
    "materials": {
        "inspect": [], "labels": ["inspect"], "morph": ["inspect", "labels"],
        "tighten": ["inspect", "morph"], "medialaxis": ["inspect", "tighten"],
        "sizingfield": ["inspect", "tighten", "medialaxis"],
        "gradlimit": ["inspect", "sizingfield"], "argmax": ["inspect", "tighten"],
        "mcinit": ["inspect", "argmax"],
        "multiparticles": ["inspect", "tighten", "gradlimit", "mcinit"],
        "tetlabel": ["inspect", "tighten", "multiparticles"],
        "meshstats": ["inspect", "gradlimit", "tetlabel"],
        "render": ["inspect", "multiparticles", "tetlabel"],
    },
}

# Stages whose tool takes --threads (the others are single-threaded).
THREADED = {"tighten", "medialaxis", "sizingfield", "gradlimit", "particles", "multiparticles"}


class StageError(Exception):
    """A tool failed (or the input cannot be meshed): status "failed" with this line."""

    def __init__(self, line, exit_code=1):
        super().__init__(line)
        self.line = line
        self.exit_code = exit_code


def error_line(stderr_text, code):
    """The line that says what went wrong: the tool's 'tool: error: ...' line if any."""
    lines = [l.strip() for l in stderr_text.splitlines() if l.strip()]
    for l in reversed(lines):
        if re.search(r"(^|: )(usage )?error: ", l):
            return l
    if code < 0:
        return f"killed by signal {-code}" + (" (out of memory?)" if -code == 9 else "")
    if lines:
        return lines[-1]
    return f"exit code {code}"


class Stage:
    def __init__(self, a):
        self.pipeline, self.name = a.pipeline, a.stage
        self.input = a.input
        self.work = a.work
        self.dir = os.path.join(a.work, a.stage)
        self.bin = a.bin
        self.threads = a.threads
        self.log = open(a.log, "w")
        self.v = dict(DEFAULTS[a.pipeline])
        self.v.update({k: str(val) for k, val in json.loads(a.vars).items() if str(val) != ""})
        self.flags = shlex.split(self.v["FLAGS"])
        self.commands = []
        self.peak_kib = 0
        self.exit_code = 0

    # --- helpers -------------------------------------------------------------
    def path(self, stage, name):
        return os.path.join(self.work, stage, name)

    def out(self, name):
        return os.path.join(self.dir, name)

    def tool(self, name):
        return os.path.join(self.bin, name)

    def threads_args(self):
        return ["--threads", str(self.threads)]

    def params(self):
        with open(self.path("inspect", "params.json")) as f:
            return json.load(f)

    def run(self, argv, stdout_path=None):
        """Run one command; its stderr goes to the log; a failure raises StageError."""
        self.commands.append(shlex.join(argv))
        self.log.write("$ " + shlex.join(argv) + "\n")
        self.log.flush()
        out = open(stdout_path + ".tmp", "w") if stdout_path else subprocess.DEVNULL
        try:
            p = subprocess.Popen(argv, stdout=out, stderr=subprocess.PIPE, text=True)
        except OSError as e:
            raise StageError(f"{argv[0]}: cannot run: {e.strerror}", 127)
        err = p.stderr.read()
        _, status, usage = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
        self.peak_kib = max(self.peak_kib, usage.ru_maxrss)  # KiB on Linux
        self.log.write(err)
        self.log.flush()
        if stdout_path:
            out.close()
            if p.returncode == 0:
                os.replace(stdout_path + ".tmp", stdout_path)
            else:
                os.remove(stdout_path + ".tmp")
        if p.returncode != 0:
            self.exit_code = p.returncode
            raise StageError(error_line(err, p.returncode), p.returncode)

    def fail(self, msg, code=1):
        self.log.write(msg + "\n")
        raise StageError(msg, code)

    # --- surface (Makefile.pipeline ch5) -----------------------------------------
    def surface_inspect(self):
        self.run([self.tool("volconv"), "--info", self.input], self.out("info.json"))
        with open(self.out("info.json")) as f:
            d = json.load(f)
        v = self.v
        labels = d.get("labels")
        kind = "mask" if v["LABELS"] or (isinstance(labels, dict) and len(labels) == 2) else "grey"
        lo, hi = d["min"], d["max"]
        if not v["LABELS"]:
            if lo == hi:
                self.fail(f'inspect: error: "{self.input}" has the value {lo:g} everywhere (an empty or '
                          "all-inside volume): no surface to mesh; expected two values (mask) or a grey-level range")
            if kind == "grey" and not v["ISO"]:
                self.fail(f'inspect: error: "{self.input}" is a grey-level volume (more than two values): '
                          "give ISO=value in the cohort sheet")
            if kind != "mask" and not lo < float(v["ISO"]) < hi:
                self.fail(f'inspect: error: "{self.input}": isovalue ISO={v["ISO"]} is outside the value range '
                          f"[{lo:g}, {hi:g}], so the volume is all inside or all outside: no surface to mesh; "
                          "expected min < ISO < max")
        minspacing = min(d["spacing"])
        use_mask = kind == "mask" or bool(v["MORPH"]) or bool(v["TIGHTEN"])
        p = {
            "kind": kind, "use_mask": use_mask,
            "hmin": float(v["HMIN"]) if v["HMIN"] else minspacing / 2,
            "field": self.path("tighten", "sdf.nrrd") if use_mask else self.input,
            "field_iso": "0" if use_mask else v["ISO"],
            "sizing": "" if v["SPACING"] else self.path("gradlimit", "h.nrrd"),
        }
        write_json(self.out("params.json"), p)

    def not_needed(self, why):
        self.status_extra = why
        return "not_needed"

    def surface_mask(self):
        p, v = self.params(), self.v
        if not p["use_mask"]:
            return self.not_needed("grey-level input: the field is the volume itself")
        if v["LABELS"]:
            extra = ["--labels", v["LABELS"]]
        elif p["kind"] == "mask":
            extra = ["--type", "uint8"]
        else:
            extra = ["--threshold", v["ISO"]]
        self.run([self.tool("volconv"), self.input, self.out("mask.nrrd"), "--no-gzip"] + extra + self.flags)

    def surface_morph(self):
        p, v = self.params(), self.v
        if not p["use_mask"]:
            return self.not_needed("grey-level input")
        st = v["STENCIL"]
        self.run([self.tool("morph"), self.path("mask", "mask.nrrd"), self.out("morph.nrrd"), "--no-gzip",
                  "--ops", f"close:{st},open:{st}"]
                 + (["--min-component", v["MIN_COMPONENT"]] if v["MIN_COMPONENT"] else [])
                 + self.flags + ["--stats", self.out("morph.json")])

    def surface_tighten(self):
        p, v = self.params(), self.v
        if p["use_mask"]:
            self.run([self.tool("tighten"), self.path("morph", "morph.nrrd"), self.out("sdf.nrrd"),
                      "--radius", v["R"], "--upsample", v["UPSAMPLE"]] + self.flags
                     + self.threads_args() + ["--stats", self.out("tighten.json")])
        else:  # Makefile.pipeline's grey_sdf.nrrd: the isosurface's signed distance
            self.run([self.tool("volconv"), self.input, self.out("sdf.nrrd"), "--no-gzip", "--distance", v["ISO"]]
                     + self.flags)

    def surface_medialaxis(self):
        if self.v["SPACING"]:
            return self.not_needed("uniform SPACING: no sizing field")
        self.run([self.tool("medialaxis"), self.path("tighten", "sdf.nrrd"), self.out("ma.ply"),
                  "--lfs-only", "--volume", self.out("ma.nrrd")] + self.flags + self.threads_args()
                 + ["--stats", self.out("medialaxis.json")])

    def surface_sizingfield(self):
        p = self.params()
        if self.v["SPACING"]:
            return self.not_needed("uniform SPACING: no sizing field")
        self.run([self.tool("sizingfield"), "--sdf", self.path("tighten", "sdf.nrrd"),
                  "--ma", self.path("medialaxis", "ma.ply"), "-o", self.out("h0.nrrd"),
                  "--eps", self.v["EPS"], "--hmin", repr(p["hmin"]), "--lfs", self.out("lfs.nrrd")]
                 + self.flags + self.threads_args() + ["--stats", self.out("sizingfield.json")])

    def gradlimit(self):
        if self.v["SPACING"]:
            return self.not_needed("uniform SPACING: no sizing field")
        self.run([self.tool("gradlimit"), self.path("sizingfield", "h0.nrrd"), self.out("h.nrrd"),
                  "--delta", self.v["DELTA"]] + self.flags + self.threads_args()
                 + ["--stats", self.out("gradlimit.json")])

    surface_gradlimit = gradlimit

    def size_args(self):
        if self.v["SPACING"]:
            return ["--spacing", self.v["SPACING"]]
        return ["--sizing", self.path("gradlimit", "h.nrrd")]

    def surface_mcinit(self):
        p = self.params()
        self.run([self.tool("mcinit"), p["field"], self.out("seeds.ply"), "--iso", p["field_iso"],
                  "--decimate", self.v["DECIMATE"]] + self.flags + ["--stats", self.out("mcinit.json")])

    def surface_particles(self):
        p, v = self.params(), self.v
        self.run([self.tool("particles"), "-i", p["field"], "--iso", p["field_iso"]] + self.size_args()
                 + ["--init", self.path("mcinit", "seeds.ply"), "--tolerance", v["PTOL"]]
                 + shlex.split(v["PFLAGS"]) + ["-o", self.out("points.ply")] + self.flags
                 + self.threads_args() + ["--stats", self.out("particles.json")])

    def surface_tetlabel(self):
        p = self.params()
        self.run([self.tool("tetlabel"), self.path("particles", "points.ply"), "-i", p["field"],
                  "--iso", p["field_iso"], "-o", self.out("surface.ply"), "--tets", self.out("volume.mesh"),
                  "--improve", self.v["IMPROVE"]] + self.flags + ["--stats", self.out("tetlabel.json")])

    def surface_meshstats(self):
        p, v = self.params(), self.v
        self.run([self.tool("meshstats"), self.path("tetlabel", "surface.ply"), "-i", p["field"],
                  "--iso", p["field_iso"]]
                 + ([] if v["SPACING"] else ["--sizing", self.path("gradlimit", "h.nrrd")])
                 + ["--seeds", self.path("mcinit", "seeds.ply"), "--min-component-seeds", "2",
                    "-o", self.out("quality.json")]
                 + (["--require", v["REQUIRE"]] if v["REQUIRE"] else []) + self.flags)

    def render(self, mesh, mesh_args, points, points_args):
        r = self.tool("render")
        self.run([r, mesh, "-o", self.out(os.path.basename(mesh)[:-4] + ".png")] + mesh_args
                 + ["--edges", "--size", "1000x1000"] + self.flags)
        self.run([r, points, "-o", self.out("points.png"), "--mode", "splats"] + points_args
                 + ["--size", "1000x1000"] + self.flags)
        # the cohort report's thumbnail (not in the makefiles)
        self.run([r, mesh, "-o", self.out("thumb.png")] + mesh_args + ["--size", "240x240"] + self.flags)

    def surface_render(self):
        self.render(self.path("tetlabel", "surface.ply"), [], self.path("particles", "points.ply"),
                    ["--color-by", "spacing"])

    # --- materials (Makefile.ch6) ------------------------------------------------
    def materials_inspect(self):
        self.run([self.tool("volconv"), "--info", self.input], self.out("info.json"))
        v = self.v
        if v["SAMPLER"] not in ("multiparticles", "stand-in"):
            self.fail(f"inspect: error: SAMPLER={v['SAMPLER']}: expected multiparticles or stand-in")
        write_json(self.out("params.json"), {
            "sizing": "" if v["SPACING"] else self.path("gradlimit", "h.nrrd")})

    def materials_labels(self):
        v = self.v
        args = [self.tool("volconv"), self.input, self.out("labels.nrrd"), "--no-gzip", "--type", "smallest"]
        if v["MERGE"]:
            args += ["--merge", v["MERGE"]]
        if v["MIN_VOXELS"] != "0":
            args += ["--min-voxels", v["MIN_VOXELS"]]
        # PAD auto: 3 voxels (times DOWNSAMPLE) where the border holds more than one label, of the
        # label holding most of the border (PAD_VALUE auto); a given PAD: a new label by default
        try:  # as Makefile.ch6's PAD_EFF: 3 when DOWNSAMPLE is not an integer (morph then refuses it)
            auto_pad = 3 * int(v["DOWNSAMPLE"])
        except ValueError:
            auto_pad = 3
        pad = f"auto:{auto_pad}" if v["PAD"] == "auto" else v["PAD"]
        if pad != "0":
            args += ["--pad", pad, "--pad-value", v["PAD_VALUE"] or ("auto" if v["PAD"] == "auto" else "new")]
        self.run(args + self.flags + ["--stats", self.out("volconv.json")])

    def materials_morph(self):
        v = self.v
        src = self.path("labels", "labels.nrrd")
        if v["MORPH_OPS"] == "none" and v["DOWNSAMPLE"] == "1":
            self.commands.append(shlex.join(["cp", src, self.out("morph.nrrd")]))
            shutil.copyfile(src, self.out("morph.nrrd"))
            return None
        self.run([self.tool("morph"), src, self.out("morph.nrrd"), "--no-gzip", "--labels", "all"]
                 + (["--ops", v["MORPH_OPS"]] if v["MORPH_OPS"] != "none" else [])
                 + (["--downsample", v["DOWNSAMPLE"]] if v["DOWNSAMPLE"] != "1" else [])
                 + ["--vote"] + self.flags + ["--stats", self.out("morph.json")])

    def materials_tighten(self):
        v = self.v
        self.run([self.tool("tighten"), self.path("morph", "morph.nrrd"), self.out("sdf_%d.nrrd"),
                  "--per-label", "--radius", v["R"], "--upsample", v["UPSAMPLE"],
                  "--outside-band", v["TIGHTEN_BAND"] or ("auto" if v["MA_SIDE"] == "inside" else "0")] + self.flags
                 + self.threads_args() + ["--stats", self.out("tighten.json")])
        with open(self.out("tighten.json")) as f:
            outputs = json.load(f)["outputs"]
        spec = ",".join("%s=%s" % (re.search(r"sdf_(-?\d+)\.nrrd$", o).group(1), o) for o in outputs)
        with open(self.out("materials.spec.tmp"), "w") as f:
            f.write(spec + "\n")
        os.replace(self.out("materials.spec.tmp"), self.out("materials.spec"))

    def materials(self):
        with open(self.path("tighten", "materials.spec")) as f:
            return f.read().strip()

    def sdfs(self):
        """(label, sdf path) of every material, from materials.spec."""
        return [tuple(item.split("=", 1)) for item in self.materials().split(",")]

    def materials_medialaxis(self):
        if self.v["SPACING"]:
            return self.not_needed("uniform SPACING: no sizing field")
        for label, sdf in self.sdfs():
            self.run([self.tool("medialaxis"), sdf, self.out(f"ma_{label}.ply"), "--side", self.v["MA_SIDE"], "--lfs-only"]
                     + self.flags + self.threads_args() + ["--stats", self.out(f"medialaxis_{label}.json")])

    def materials_sizingfield(self):
        if self.v["SPACING"]:
            return self.not_needed("uniform SPACING: no sizing field")
        args = []
        for label, sdf in self.sdfs():
            args += ["--sdf", sdf, "--ma", self.path("medialaxis", f"ma_{label}.ply")]
        hmin = self.v["HMIN"]
        if hmin == "auto":  # half the radius tighten used; on a tiny, upsampled volume the radius itself
            with open(self.path("tighten", "tighten.json")) as f:
                t = json.load(f)["parameters"]
            hmin = str(t["radius"] / (1 if t["upsample"] > 1 else 2))
        self.run([self.tool("sizingfield")] + args + ["-o", self.out("h0.nrrd"), "--eps", self.v["EPS"],
                  "--hmin", hmin] + self.flags + self.threads_args()
                 + ["--stats", self.out("sizingfield.json")])

    materials_gradlimit = gradlimit

    def materials_argmax(self):
        self.run([self.tool("volconv"), self.materials(), self.out("argmax.nrrd"), "--no-gzip", "--argmax"] + self.flags)

    def materials_mcinit(self):
        self.run([self.tool("mcinit"), self.path("argmax", "argmax.nrrd"), self.out("junction_seeds.ply"),
                  "--junctions", "--decimate", self.v["DECIMATE"]] + self.flags
                 + ["--stats", self.out("mcinit.json")])

    def materials_multiparticles(self):
        v = self.v
        seeds = self.path("mcinit", "junction_seeds.ply")
        if v["SAMPLER"] == "stand-in":
            self.commands.append(shlex.join(["cp", seeds, self.out("points.ply")]))
            shutil.copyfile(seeds, self.out("points.ply"))
            return None
        self.run([self.tool("multiparticles"), "--materials", self.materials(), "--seeds", seeds]
                 + self.size_args() + ["--material-kernel", v["KERNEL"]] + shlex.split(v["MPFLAGS"])
                 + ["-o", self.out("points.ply")]
                 + self.flags + self.threads_args() + ["--stats", self.out("multiparticles.json")])

    def materials_tetlabel(self):
        self.run([self.tool("tetlabel"), self.path("multiparticles", "points.ply"), "--materials",
                  self.materials(), "--kernel", self.v["KERNEL"], "-o", self.out("interfaces.ply"),
                  "--material-surfaces", self.dir,
                  "--tets", self.out("volume.mesh"), "--improve", self.v["IMPROVE"]] + self.flags
                 + ["--stats", self.out("tetlabel.json")])

    def materials_meshstats(self):
        v = self.v
        self.run([self.tool("meshstats"), self.path("tetlabel", "interfaces.ply")]
                 + ([] if v["SPACING"] else ["--sizing", self.path("gradlimit", "h.nrrd")])
                 + ["-o", self.out("quality.json")]
                 + (["--require", v["REQUIRE"]] if v["REQUIRE"] else []) + self.flags)

    def materials_render(self):
        self.render(self.path("tetlabel", "interfaces.ply"), ["--color-by", "pair"],
                    self.path("multiparticles", "points.ply"), ["--color-by", "junction"])

    # --- the stage as a whole --------------------------------------------------
    def execute(self):
        os.makedirs(self.dir, exist_ok=True)
        t0 = time.monotonic()
        status, error, note = "ok", None, None
        self.status_extra = None
        upstream = [s for s in STAGES[self.pipeline][self.name] if read_status(self.work, s) in
                    ("failed", "skipped", None)]
        if upstream:
            status = "skipped"
            note = f"stage {upstream[0]} did not succeed"
        else:
            try:
                r = getattr(self, f"{self.pipeline}_{self.name}")()
                if r == "not_needed":
                    status, note = "not_needed", self.status_extra
            except StageError as e:
                status, error = "failed", e.line
                self.exit_code = self.exit_code or e.exit_code
        st = {
            "scan_input": self.input, "pipeline": self.pipeline, "stage": self.name, "status": status,
            "error": error, "note": note, "exit_code": self.exit_code, "commands": self.commands,
            "seconds": round(time.monotonic() - t0, 3),
            "peak_rss_mib": round(self.peak_kib / 1024, 1) if self.peak_kib else None,
            "threads": self.threads,
        }
        write_json(os.path.join(self.dir, "status.json"), st)
        self.log.write(f"# stage {self.name}: {status}" + (f": {error}" if error else "") + "\n")
        self.log.close()


def read_status(work, stage):
    try:
        with open(os.path.join(work, stage, "status.json")) as f:
            return json.load(f)["status"]
    except (OSError, ValueError, KeyError):
        return None


def write_json(path, obj):
    with open(path + ".tmp", "w") as f:
        json.dump(obj, f, indent=1)
        f.write("\n")
    os.replace(path + ".tmp", path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("pipeline", choices=sorted(STAGES))
    ap.add_argument("stage")
    ap.add_argument("--input", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--bin", required=True)
    ap.add_argument("--vars", default="{}")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--log", required=True)
    a = ap.parse_args()
    if a.stage not in STAGES[a.pipeline]:
        ap.error(f"stage {a.stage!r} is not a {a.pipeline} stage; expected one of {', '.join(STAGES[a.pipeline])}")
    Stage(a).execute()


if __name__ == "__main__":
    main()
