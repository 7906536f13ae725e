#!/usr/bin/env python3
"""Writes the Monte Carlo reference of the void duct (scenes/duct.toml) for the DOM test
tests/verification/dom/emission_test.cpp: per detector cell, the MC fluence_diffuse and its
standard error, from a `nimbus run ... --set model.name=montecarlo` HDF5 file.

Regions (cells [lo, hi) per axis; the duct is x 4..19, y and z 10..13):
  end     x 20..21, y z 10..13   the medium the duct's light lands on (32 cells)
  wall    x 14..19, the ring of medium cells around the duct (y or z in {9, 14}) (120 cells)
  source  x 2..3,   y z 10..13   inside the emitting box (32 cells; light local and diffuse)
Usage: /usr/bin/python3 jobs/duct/extract_reference.py run.h5 out.csv"""
import sys

import h5py
import numpy as np


def regions():
    end = [(i, j, k) for k in range(10, 14) for j in range(10, 14) for i in range(20, 22)]
    wall = [(i, j, k) for k in range(9, 15) for j in range(9, 15) for i in range(14, 20)
            if j in (9, 14) or k in (9, 14)]
    source = [(i, j, k) for k in range(10, 14) for j in range(10, 14) for i in range(2, 4)]
    return {"end": end, "wall": wall, "source": source}


def main(path, out):
    with h5py.File(path, "r") as f:
        phi = np.asarray(f["fields/fluence_diffuse/gray"])           # [z][y][x]
        se = np.asarray(f["fields/fluence_diffuse_stderr/gray"])
        report = f["/run"].attrs["report"]
        toml = f["/scene"].attrs["toml"]
    if isinstance(report, bytes):
        report = report.decode()
    if isinstance(toml, bytes):
        toml = toml.decode()
    photons = [l for l in toml.splitlines() if l.startswith("photons")][0]
    seed = [l for l in toml.splitlines() if l.startswith("seed =")][-1]
    with open(out, "w") as o:
        o.write("# Monte Carlo reference of scenes/duct.toml (jobs/duct/make_reference.sh): "
                f"{photons}, {seed}; fluence_diffuse W/m^2 and its standard error (batch means)\n")
        o.write("region,i,j,k,mean,stderr\n")
        for name, cells in regions().items():
            rel = []
            for (i, j, k) in cells:
                o.write(f"{name},{i},{j},{k},{phi[k, j, i]:.9e},{se[k, j, i]:.4e}\n")
                rel.append(se[k, j, i] / phi[k, j, i])
            print(f"{name}: {len(cells)} cells, mean fluence {np.mean([phi[k, j, i] for i, j, k in cells]):.4e}, "
                  f"relative standard error median {np.median(rel):.4f}, max {np.max(rel):.4f}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
