#!/usr/bin/python3
r"""Speed against error (issue 3 item 5): every model on every scene, against a Monte Carlo reference.

For each scene: one long Monte Carlo reference run, then one run per model setting; each run is
compared with `nimbus compare --json` against the reference (relative L2 and max relative error
of fluence_diffuse over cells with density, and the ratio of the totals, per band; image RMSE
when both runs wrote images).
Writes study.csv, study.json and study.png (log-log wall time against relative L2 error, one
panel per scene, one marker per model) into --out.

Usage (Debian's python3 has numpy, h5py and matplotlib):
  /usr/bin/python3 jobs/study.py --scenes scenes/default.toml \
      --model single=single \
      --model diffusion=diffusion \
      --model mc-1e5=montecarlo,model.montecarlo.photons=100000 \
      --reference-photons 10000000 --ranks 2 --out study
A model is LABEL=NAME[,key=value,...]: NAME goes to model.name, each key=value to --set.
--set key=value applies to every run (e.g. --set grid.n=[48,48,32] for a quick study).
--repeats N runs every model N times, in rounds over the scene's models (so that a slow spell
of a shared machine falls on different models, not on one model's every run), and reports the
median wall and model times with their spread (solve_s_min, solve_s_max); the errors are those
of the first round (the models are deterministic: same settings, same fields).
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import time

import h5py


MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")


def mpi_command(args, sub, scene, sets):
    """`mpiexec -n R nimbus SUB SCENE --set ...` on args.ranks ranks."""
    cmd = ["mpiexec", "-n", str(args.ranks), "--oversubscribe", "--bind-to", "none", args.nimbus, sub, scene]
    for s in sets:
        cmd += ["--set", s]
    return cmd


def reference_sets(args):
    """The settings of a scene's Monte Carlo reference run."""
    return args.set + ["model.name=montecarlo", f"model.montecarlo.photons={args.reference_photons}"] + args.reference_set


def run_nimbus(args, scene, sets, out_dir):
    """Runs `mpiexec -n R nimbus run SCENE --set ... --out DIR`; returns (wall seconds, report)."""
    os.makedirs(out_dir, exist_ok=True)
    # Scenes may name their outputs or switch the HDF5 file off: the study reads DIR/nimbus.h5.
    cmd = mpi_command(args, "run", scene, sets) + ["--set", "output.name=nimbus", "--set", "output.hdf5=true",
                                                   "--out", out_dir]
    print("+", " ".join(cmd), flush=True)
    start = time.monotonic()
    with open(os.path.join(out_dir, "log.txt"), "w") as log:
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, env=MPI_ENV).returncode
    wall = time.monotonic() - start
    if rc != 0:
        with open(os.path.join(out_dir, "log.txt")) as log:
            errors = [l.strip() for l in log if "error:" in l]
        raise RuntimeError(f"nimbus run failed ({rc}): {errors[0] if errors else ''} (log: {out_dir}/log.txt)")
    report = {}
    with h5py.File(os.path.join(out_dir, "nimbus.h5"), "r") as f:
        if "run" in f and "report" in f["run"].attrs:
            raw = f["run"].attrs["report"]
            report = json.loads(raw.decode() if isinstance(raw, bytes) else raw)
    return wall, report


def preflight(args, scene, sets):
    """`nimbus info` with the run's settings on args.ranks ranks: the checks a run makes before it
    computes, in about a second, so that a bad model or key stops the study before the long
    reference run. Returns None if the scene would run, else nimbus's error line."""
    cmd = mpi_command(args, "info", scene, sets)
    r = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=MPI_ENV)
    if r.returncode == 0:
        return None
    errors = [l.strip() for l in r.stderr.splitlines() if "error:" in l]
    return errors[0] if errors else f"exit {r.returncode}: {r.stderr.strip()[-300:]}"


def compare(args, run_dir, ref_dir):
    cmd = [args.nimbus, "compare", os.path.join(run_dir, "nimbus.h5"), os.path.join(ref_dir, "nimbus.h5"), "--json"]
    a_img, b_img = os.path.join(run_dir, "nimbus.exr"), os.path.join(ref_dir, "nimbus.exr")
    if os.path.exists(a_img) and os.path.exists(b_img):
        cmd += ["--image-a", a_img, "--image-b", b_img]
    out = subprocess.run(cmd, capture_output=True, text=True, env=MPI_ENV)
    if out.returncode != 0:
        raise RuntimeError(f"nimbus compare failed: {out.stderr.strip()}")
    return json.loads(out.stdout)


def parse_model(spec):
    label, _, rest = spec.partition("=")
    parts = rest.split(",")
    if not label or not parts[0]:
        raise SystemExit(f"bad --model '{spec}': expected LABEL=NAME[,key=value,...]")
    return label, ["model.name=" + parts[0]] + [p for p in parts[1:] if p]


def solve_seconds(report):
    """The model's own time: the pipeline's top-level "model" phase, else the report's total."""
    for p in report.get("phases", []):
        if p["name"] == "model":
            return p["seconds"]
    # The HDF5 file stores the report as it stood before the output was written: no
    # "total_seconds" yet, but the pipeline's "total_seconds_before_output" among its values.
    return report.get("values", {}).get("total_seconds_before_output", float("nan"))


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    scenes = sorted({r["scene"] for r in rows})
    labels = sorted({r["model"] for r in rows})
    markers = "osD^v<>pXh*"
    colors = plt.get_cmap("tab20").colors
    # One marker and colour per model across every panel, one legend beside the panels.
    style = {label: (markers[i % len(markers)], colors[i % len(colors)]) for i, label in enumerate(labels)}
    ncols = min(3, len(scenes))
    nrows = (len(scenes) + ncols - 1) // ncols
    fig, axes = plt.subplots(nrows, ncols, figsize=(5 * ncols + 2, 4 * nrows), squeeze=False)
    for ax in axes.flat[len(scenes):]:
        ax.set_visible(False)
    for ax, scene in zip(axes.flat, scenes):
        for label in labels:
            pts = [(r["wall_s"], r["rel_l2"]) for r in rows if r["scene"] == scene and r["model"] == label and r["rel_l2"] > 0]
            if pts:
                m, c = style[label]
                ax.loglog(*zip(*pts), m, color=c, markersize=8)
        ax.set_title(os.path.basename(scene))
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel("relative L2 error of fluence_diffuse")
        ax.grid(True, which="both", alpha=0.3)
    handles = [Line2D([], [], linestyle="", marker=style[l][0], color=style[l][1], markersize=8) for l in labels]
    fig.legend(handles, labels, loc="center right", fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1 - 1.6 / (5 * ncols + 2), 1))
    fig.savefig(path, dpi=120)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenes", nargs="+", required=True)
    p.add_argument("--model", action="append", required=True, help="LABEL=NAME[,key=value,...] (repeatable)")
    p.add_argument("--set", action="append", default=[], help="key=value for every run (repeatable)")
    p.add_argument("--reference-photons", type=int, default=10_000_000)
    p.add_argument("--reference-set", action="append", default=[], help="extra key=value for the reference")
    p.add_argument("--ranks", type=int, default=2)
    p.add_argument("--nimbus", default=os.path.join("build", "bin", "nimbus"))
    p.add_argument("--out", default="study")
    p.add_argument("--repeats", type=int, default=1,
                   help="runs per model, in rounds; times are the medians (default 1)")
    p.add_argument("--reuse-reference", action="store_true",
                   help="keep OUT/<scene>/reference/nimbus.h5 when it exists (same scene and settings!)")
    args = p.parse_args()
    if args.repeats < 1:
        raise SystemExit(f"study: --repeats must be >= 1, not {args.repeats}")
    models = [parse_model(m) for m in args.model]
    if not (os.path.isfile(args.nimbus) and os.access(args.nimbus, os.X_OK)):
        raise SystemExit(f"study: no nimbus executable at {args.nimbus} (build it: bash jobs/build.sh; or --nimbus PATH)")
    # Every run's settings checked before anything long runs: a model that does not support a
    # scene is skipped later with its reason; any other refusal stops the study here.
    # Each scene's runs go to OUT/<file name without .toml>: two scenes of one name would share it.
    tags = [os.path.splitext(os.path.basename(scene))[0] for scene in args.scenes]
    for tag in set(tags):
        if tags.count(tag) > 1:
            same = [scene for scene, t in zip(args.scenes, tags) if t == tag]
            raise SystemExit(f"study: scenes {', '.join(same)} would share the folder {args.out}/{tag}: rename one")
    for scene in args.scenes:
        ref_sets = reference_sets(args)
        for label, sets in [("reference", ref_sets)] + [(label, args.set + sets) for label, sets in models]:
            error = preflight(args, scene, sets)
            if error and not (label != "reference" and "does not support" in error):
                raise SystemExit(f"study: {scene} {label}: {error}")
    os.makedirs(args.out, exist_ok=True)

    rows = []
    for scene in args.scenes:
        tag = os.path.splitext(os.path.basename(scene))[0]
        ref_dir = os.path.join(args.out, tag, "reference")
        ref_sets = reference_sets(args)
        if args.reuse_reference and os.path.exists(os.path.join(ref_dir, "nimbus.h5")):
            ref_wall = float("nan")
            print(f"{tag}: reusing the reference in {ref_dir}", flush=True)
        else:
            ref_wall, _ = run_nimbus(args, scene, ref_sets, ref_dir)
            print(f"{tag}: reference done in {ref_wall:.1f} s", flush=True)
        # Rounds over the models; a model that refuses the scene (e.g. volume sources with single
        # or psf) is skipped with its reason; any other failure stops the study.
        runs, skipped = {}, set()  # label -> {"wall": [...], "solve": [...], "cmp": compare()}
        for round_ in range(args.repeats):
            for label, sets in models:
                if label in skipped:
                    continue
                run_dir = os.path.join(args.out, tag, label)
                try:
                    wall, report = run_nimbus(args, scene, args.set + sets, run_dir)
                except RuntimeError:
                    with open(os.path.join(run_dir, "log.txt")) as log:
                        refusal = [l.strip() for l in log if "does not support" in l]
                    if not refusal:
                        raise
                    print(f"{tag} {label}: skipped: {refusal[0]}", flush=True)
                    skipped.add(label)
                    continue
                run = runs.setdefault(label, {"wall": [], "solve": []})
                run["wall"].append(wall)
                run["solve"].append(solve_seconds(report))
                if round_ == 0:
                    run["cmp"] = compare(args, run_dir, ref_dir)
                print(f"{tag} {label}: {wall:.2f} s (round {round_ + 1} of {args.repeats})", flush=True)
        for label, sets in models:
            if label not in runs:
                continue
            run = runs[label]
            cmp = run["cmp"]
            # Bands whose relative errors are undefined (a zero reference: null, with "undefined")
            # are left out of the means; NaN if none is left.
            bands = [b for b in cmp["bands"] if b["rel_l2"] is not None]
            nan = float("nan")
            row = {
                "scene": scene, "model": label, "settings": " ".join(sets), "ranks": args.ranks,
                "wall_s": statistics.median(run["wall"]), "solve_s": statistics.median(run["solve"]),
                "rel_l2": sum(b["rel_l2"] for b in bands) / len(bands) if bands else nan,
                "max_rel": max((b["max_rel"] for b in bands), default=nan),
                # the totals' ratio (bias), mean over the bands; NaN where undefined
                "sum_ratio": sum(nan if b.get("sum_ratio") is None else b["sum_ratio"] for b in bands) / len(bands) if bands else nan,
                "rms_z": sum(nan if b.get("rms_z") is None else b["rms_z"] for b in bands) / len(bands) if bands else nan,
                "image_rmse": cmp.get("image", {}).get("rmse", float("nan")),
                "image_rel": nan if cmp.get("image", {}).get("rel_error") is None else cmp["image"]["rel_error"],
                "reference_wall_s": ref_wall,
                "repeats": len(run["solve"]),
                "solve_s_min": min(run["solve"]), "solve_s_max": max(run["solve"]),
            }
            rows.append(row)
            print(f"{tag} {label}: {row['wall_s']:.2f} s (median), relative L2 {row['rel_l2']:.3e}, "
                  f"max {row['max_rel']:.3e}", flush=True)

    if not rows:
        raise SystemExit("study: no model ran on any scene (every one was skipped); nothing to write")
    with open(os.path.join(args.out, "study.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    with open(os.path.join(args.out, "study.json"), "w") as f:
        json.dump(rows, f, indent=2)
    plot(rows, os.path.join(args.out, "study.png"))
    print(f"wrote {args.out}/study.csv, study.json, study.png")


if __name__ == "__main__":
    try:
        sys.exit(main())
    except RuntimeError as e:  # a failed nimbus run or compare: its message, not a traceback
        sys.exit(f"study: {e}")
