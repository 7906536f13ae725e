#!/usr/bin/env python3
"""The diffusion model on optically thick cells, in one dimension (solvers/diffusion/README.md,
"Optically thick cells").

A slab of 4 cells under an overhead sun (E0 = 1, vacuum on both sides) is solved with the
model's own scheme (diffusion_kernel.h: cell-centred P1, face D and G from the two cells,
Marshak faces by ghost elimination, the first-scatter source Q0 = kappa a T / 4π integrated over
each cell) and compared with the same P1 equation on 3000 cells. The only difference is the
discretization, so the ratio of the totals of U is the scheme's error on thick cells.

Three ways to place each cell's first-scatter source are compared:
  centre  the model's until the thirty-ninth session: the cell integral of Q0 at the cell
          centre. The light scattered within a mean free path of the lit face sits half a cell
          under it, behind the half cell's diffusion resistance h / (2D), and cannot get out.
  sheet   the model's now (sources.cpp, sheet_escape; diffusion_kernel.h, marshak_escape): in
          the cell under the Marshak face the light enters by, the share of the source that
          leaves through the face is the Green's function of -D u'' + sigma_a u on the half cell
          between the centre (held) and the face (Marshak, u + 2D u' = 0, outflow u/2), taken at
          the source's centroid d ((h/2) L(kappa h / 2) from the centre for e^{-kappa z},
          L(y) = coth y - 1/y): sinh(k d) / (sinh(k l) + 2 D k cosh(k l)), k = sqrt(sigma_a / D),
          l = h/2; d / (l + 2D) as k -> 0.
  spread  the same at the face, and in every other cell the source split toward the lit
          neighbour's centre by sinh(k d) / sinh(k h) (the linear hat weights as k -> 0): no
          better here, and in 3-D it would move sources between ranks.
  sheet+G the sheet, and the lit cell's forward flux G (Q1 / kappa_tr, the same e^{-kappa z}
          profile) split between the cell's two faces as the profile splits between its halves:
          the face above takes 2p G, the face below 2(1 - p) G, p = 1 / (1 + e^{-kappa h / 2}),
          where the scheme gives each the cell's G (so half of a thick cell's G reaches the
          face below, where the true G is e^{-kappa h} of the top's). Not in the model: closer at
          kappa h = 20 with albedo 0.9 (0.92 -> 1.00), further at 5-10 with albedo 0.999
          (1.02 -> 1.04, 1.01 -> 1.05).
The delta-Eddington rows solve with the model's scaled optics (delta_scaling.h).
Usage: /usr/bin/python3 jobs/diffusion_thick_cells.py
"""
import numpy as np


def tridiagonal_solve(lower, diag, upper, rhs):
    """Thomas algorithm: lower[i] couples row i to i-1, upper[i] to i+1."""
    n = len(rhs)
    c = np.zeros(n)
    d = np.zeros(n)
    c[0] = upper[0] / diag[0]
    d[0] = rhs[0] / diag[0]
    for i in range(1, n):
        m = diag[i] - lower[i] * c[i - 1]
        c[i] = upper[i] / m if i < n - 1 else 0.0
        d[i] = (rhs[i] - lower[i] * d[i - 1]) / m
    x = np.zeros(n)
    x[-1] = d[-1]
    for i in range(n - 2, -1, -1):
        x[i] = d[i] - c[i] * x[i + 1]
    return x


def solve_slab(ncell, depth, sigma_t, albedo, g, placement="centre"):
    """Total of U (W/m² per 4π, times m) over a slab `depth` metres thick of ncell cells."""
    h = depth / ncell
    kappa_tr = sigma_t * (1 - albedo * g)
    D = 1 / (3 * kappa_tr)
    sigma_a = sigma_t * (1 - albedo)
    x = sigma_t * h  # optical thickness of a cell
    top = np.arange(ncell) * h  # each cell's lit (upper) face
    t_mean = np.exp(-sigma_t * top) * -np.expm1(-x) / x  # exact cell mean of T
    q0 = sigma_t * albedo / (4 * np.pi) * t_mean
    source = q0 * h  # per unit area
    G = g * q0 / kappa_tr  # Q1 / kappa_tr, Q1 = g q0 w, w = +z (down)
    placed = source.copy()
    split_g = np.zeros(ncell)  # the lit cell's G: face above G + split_g, face below G - split_g
    if placement == "sheet+G":
        split_g[0] = (2 / (1 + np.exp(-x / 2)) - 1) * G[0]
    if placement in ("sheet", "spread", "sheet+G"):
        k = np.sqrt(sigma_a / D)
        d = 0.5 * h * (1 / np.tanh(x / 2) - 2 / x)  # centroid of e^{-sigma z} above the centre

        def share(length):
            return d / length if k * length < 1e-8 else np.sinh(k * d) / np.sinh(k * length)

        for c in range(ncell):
            if c == 0:  # under the Marshak face the light enters by: what leaves through it
                l = h / 2
                if k * l < 1e-8:
                    out = d / (l + 2 * D)
                else:
                    out = np.sinh(k * d) / (np.sinh(k * l) + 2 * D * k * np.cosh(k * l))
                placed[c] -= source[c] * out
            elif placement == "spread":  # toward the lit neighbour's centre
                moved = source[c] * share(h)
                placed[c] -= moved
                placed[c - 1] += moved
    # Cell balance per unit area: Σ_faces D (U_P - U_N)/h + sigma_a h U_P = S - Σ_faces G_f n_out
    lower = np.zeros(ncell)
    upper = np.zeros(ncell)
    diag = np.full(ncell, sigma_a * h)
    rhs = placed.copy()
    for c in range(ncell):
        for nb, n_out in ((c - 1, -1), (c + 1, 1)):
            if 0 <= nb < ncell:
                diag[c] += D / h
                if nb < c:
                    lower[c] = -D / h
                else:
                    upper[c] = -D / h
                # the face's G from each side: the cell's G, less split_g on its lower face
                rhs[c] -= 0.5 * (G[c] - n_out * split_g[c] + G[nb] + n_out * split_g[nb]) * n_out
            else:  # Marshak: diagonal 2D/(h + 4D), rhs (n·G) h/(h + 4D), n = -n_out
                diag[c] += 2 * D / (h + 4 * D)
                rhs[c] -= n_out * (G[c] - n_out * split_g[c]) * h / (h + 4 * D)
    return tridiagonal_solve(lower, diag, upper, rhs).sum() * h


def main():
    print("total U of 4 cells / total U of 3000 cells, slab of 4 kappa h, overhead sun")
    print(f"{'optics':>34} {'kappa h':>8} {'centre':>7} {'sheet':>7} {'spread':>7} {'sheet+G':>7}")
    cases = [(0.999, 0.0, False), (0.9, 0.0, False), (0.5, 0.0, False),
             (0.999, 0.85, True), (0.9, 0.85, True), (0.99, 0.5, True)]
    for albedo, g, scaled in cases:
        sigma_t, a, gg = 1.0, albedo, g
        if scaled:  # delta-Eddington: f = g², the model's default for the sun's source
            f = g * g
            sigma_t, a, gg = 1 - albedo * f, albedo * (1 - f) / (1 - albedo * f), (g - f) / (1 - f)
        label = f"a {albedo}, g {g}" + (" (delta-Eddington)" if scaled else "")
        for kh in (1, 2, 5, 10, 20):
            depth = 4 * kh / 1.0  # kappa h in units of the unscaled extinction (sigma_t = 1)
            fine = solve_slab(3000, depth, sigma_t, a, gg)
            ratios = [solve_slab(4, depth, sigma_t, a, gg, p) / fine for p in ("centre", "sheet", "spread", "sheet+G")]
            print(f"{label:>34} {kh:>8} " + " ".join(f"{r:7.3f}" for r in ratios))


if __name__ == "__main__":
    main()
