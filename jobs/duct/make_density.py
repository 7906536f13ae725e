#!/usr/bin/env python3
"""Writes scenes/duct.raw, the density of scenes/duct.toml: a 24^3 block of density 1 with a
square void duct (density 0) of 4 x 4 cells along x, cells x 4..19, y and z 10..13 (it stops
4 cells before the far face, so the light streaming down it lands on medium cells that the
Monte Carlo model tallies). float32 little-endian, x fastest ([z][y][x]), as medium.kind = "raw".
Usage: /usr/bin/python3 jobs/duct/make_density.py [out.raw]"""
import os
import sys

import numpy as np

N = 24
DUCT_X = (4, 20)      # [lo, hi) cells
DUCT_YZ = (10, 14)

rho = np.ones((N, N, N), dtype="<f4")  # [z][y][x]
rho[DUCT_YZ[0]:DUCT_YZ[1], DUCT_YZ[0]:DUCT_YZ[1], DUCT_X[0]:DUCT_X[1]] = 0.0
here = os.path.dirname(os.path.abspath(__file__))
out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "..", "scenes", "duct.raw")
rho.tofile(out)
print(f"wrote {out}: {N}^3 cells, {int((rho == 0).sum())} empty (the duct)")
