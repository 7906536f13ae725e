#!/usr/bin/env python3
"""dom's step scheme on a bright, optically thick box: how much fluence_diffuse it loses to its
numerical diffusion, against Monte Carlo, as the cells get thinner (solvers/dom/README.md,
"The step scheme's numerical diffusion"; the warning in solvers/dom/dom.cpp).

The box is 4 m wide in an 8 m domain (grid fractions 0.25-0.75), 20 mean free paths across,
albedo 0.999 (or --albedo), g 0, lit either by an overhead sun or by a volume source filling it.
The step scheme's diffusion limit has D = 1/(3 kappa_tr) + h/4, so the ratio to Monte Carlo should
approach 1 at first order in h; the diamond scheme is second order. Prints one markdown table of
the total fluence_diffuse over the cells with density, model / Monte Carlo.

    source jobs/env.sh; /usr/bin/python3 jobs/dom_step_diffusion.py [--nimbus build/bin/nimbus]
"""
import argparse
import os
import subprocess
import sys
import tempfile

import h5py


SCENE = """title = "bright box"
[grid]
n = [{n}, {n}, {n}]
cell_size = {h}
unit = "m"
[medium]
kind = "box"
density = 1.0
box_lo = [0.25, 0.25, 0.25]
box_hi = [0.75, 0.75, 0.75]
[[optics]]
name = "gray"
sigma_t = {kappa}
albedo = {albedo}
g = 0.0
[sun]
direction = [0.0, 0.0, -1.0]
irradiance = 1.0
[sky]
radiance = 0.0
[light]
method = "exact"
[output]
image = false
"""


def total(path):
    with h5py.File(path, "r") as f:
        rho = f["fields/density"][...]
        return float(f["fields/fluence_diffuse/gray"][...][rho > 0].sum())


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--nimbus", default="build/bin/nimbus")
    p.add_argument("--ranks", type=int, default=2)
    p.add_argument("--albedo", type=float, default=0.999)
    p.add_argument("--photons", type=int, default=400000)
    p.add_argument("--cells", type=int, nargs="+", default=[8, 16, 32, 64], help="cells across the domain")
    args = p.parse_args()
    if not os.path.exists(args.nimbus):
        sys.exit(f"no nimbus at {args.nimbus} (build it: bash jobs/build.sh)")
    kappa = 20.0 / 4.0  # 20 mean free paths across 4 m
    lights = {
        "sun": ["--set", "sun.direction=[0.0,0.0,-1.0]"],
        "source": ["--set", "sun.enabled=false", "--set", "sources=[{lo=[2.0,2.0,2.0],hi=[6.0,6.0,6.0],power=1.0}]"],
    }
    models = {
        "mc": ["--set", 'model.name="montecarlo"', "--set", f"model.montecarlo.photons={args.photons}"],
        "step": ["--set", 'model.name="dom"'],
        "diamond": ["--set", 'model.name="dom"', "--set", 'model.dom.scheme="diamond"',
                    "--set", 'model.dom.iteration="gmres"'],
    }
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.cells:
            h = 8.0 / n
            scene = os.path.join(tmp, f"box{n}.toml")
            with open(scene, "w") as f:
                f.write(SCENE.format(n=n, h=h, kappa=kappa, albedo=args.albedo))
            common = [scene]
            row = [n, kappa * h]
            for lname, lset in lights.items():
                t = {}
                for mname, mset in models.items():
                    out = os.path.join(tmp, f"{n}_{lname}_{mname}")
                    cmd = ["mpiexec", "-n", str(args.ranks), "--oversubscribe", "--bind-to", "none", args.nimbus,
                           "run", *common, *lset, *mset, "--out", out]
                    r = subprocess.run(cmd, capture_output=True, text=True)
                    if r.returncode != 0:
                        sys.exit(f"failed: {' '.join(cmd)}\n{r.stderr[-2000:]}")
                    t[mname] = total(os.path.join(out, "nimbus.h5"))
                row += [t["step"] / t["mc"], t["diamond"] / t["mc"]]
            rows.append(row)
            print(f"{n}³ done", file=sys.stderr)
    print(f"\nbox 20 mean free paths wide, albedo {args.albedo}, g 0; total fluence_diffuse / Monte Carlo's "
          f"({args.photons} photons), {args.ranks} ranks\n")
    print("| cells across | kappa h | (3/4) kappa_tr h | sun: step | sun: diamond | source: step | source: diamond |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for n, kh, ss, sd, vs, vd in rows:
        print(f"| {n} | {kh:.3g} | {0.75 * kh:.3g} | {ss:.3f} | {sd:.3f} | {vs:.3f} | {vd:.3f} |")


if __name__ == "__main__":
    main()
