#!/usr/bin/env python3
"""Fourier analysis of DOM's DSA in an infinite homogeneous medium (solvers/dom/dsa.h).

A Fourier error mode exp(i lam z) (lam in units of the scaled extinction kappa*) is swept once
(psi = S / (1 + i lam Omega_z), exact in space, product Gauss quadrature in angle) with the
scattering of the real spherical-harmonic moments up to L (delta-M scaled HG, as the DOM model
builds it), then corrected by
  dsa       the isotropic correction only:  delta = sigma_s R0 / (lam^2 D + sigma_a)
  p1        the current too (P1 synthetic acceleration), G = chi_1 sigma_s R1 / kappa_tr
  filtered  the same with G filtered by (kappa_tr - nu lap) G_f = kappa_tr G, nu = 0.2 / kappa*
and the largest |eigenvalue| over lam of the moments' iteration matrix is printed: the spectral
radius, the error's factor per iteration. Usage: /usr/bin/python3 jobs/dsa_fourier.py
"""
import numpy as np
from numpy.polynomial import legendre


def real_sh(L, x, y, z):
    """Real orthonormal spherical harmonics, index l*l + l + m (src/physics/angular_moments.h)."""
    mu = np.clip(z, -1, 1)
    s = np.sqrt(np.maximum(0, 1 - mu * mu))
    phi = np.arctan2(y, x)
    Pb = {}
    pmm = np.ones_like(mu) / np.sqrt(4 * np.pi)
    for m in range(L + 1):
        if m > 0:
            pmm = pmm * s * np.sqrt((2 * m + 1) / (2 * m))
        Pb[m, m] = pmm
        if m + 1 <= L:
            Pb[m + 1, m] = np.sqrt(2 * m + 3) * mu * pmm
        for l in range(m + 2, L + 1):
            a = np.sqrt((4 * l * l - 1) / (l * l - m * m))
            b = np.sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1))
            Pb[l, m] = a * (mu * Pb[l - 1, m] - b * Pb[l - 2, m])
    Y = np.zeros(((L + 1) ** 2,) + mu.shape)
    for l in range(L + 1):
        Y[l * l + l] = Pb[l, 0]
        for m in range(1, l + 1):
            c = np.sqrt(2) * Pb[l, m]
            Y[l * l + l + m] = c * np.cos(m * phi)
            Y[l * l + l - m] = c * np.sin(m * phi)
    return Y


def quadrature(n_mu=16, n_phi=32):
    mu, wm = legendre.leggauss(n_mu)
    ph = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    MU, PH = np.meshgrid(mu, ph, indexing="ij")
    w = np.outer(wm, np.full(n_phi, 2 * np.pi / n_phi)).ravel()
    z = MU.ravel()
    return np.sqrt(1 - z * z) * np.cos(PH.ravel()), np.sqrt(1 - z * z) * np.sin(PH.ravel()), z, w


def spectral_radius(albedo, g, L, method, nu=0.2):
    f = g ** (L + 1) if g > 0 else 0.0  # delta-M, forward peaks only (band_problem.h)
    chi = np.array([(g ** l - f) / (1 - f) for l in range(L + 1)])
    sigma_s = albedo * (1 - f) / (1 - albedo * f)  # kappa* = 1
    sigma_a, kappa_tr = 1 - sigma_s, 1 - chi[1] * sigma_s
    D = 1 / (3 * kappa_tr)
    x, y, z, w = quadrature()
    Y = real_sh(L, x, y, z)
    nmom = (L + 1) ** 2
    degree = np.array([int(np.sqrt(k)) for k in range(nmom)])
    y0, y1 = 1 / np.sqrt(4 * np.pi), np.sqrt(3 / (4 * np.pi))
    worst = 0.0
    for lam in np.concatenate([np.linspace(1e-4, 3, 150), np.linspace(3, 60, 60)]):
        sweep = (Y * w) @ ((sigma_s * chi[degree])[:, None] * Y / (1 + 1j * lam * z)).T
        M = sweep.copy()
        R = sweep - np.eye(nmom)
        R0 = R[0] / y0
        R1 = np.array([R[3], R[1], R[2]]) / y1  # (x, y, z) flux change
        G = np.zeros_like(R1) if method == "dsa" else chi[1] * sigma_s * R1 / kappa_tr
        if method == "filtered":
            G = G / (1 + nu * lam ** 2 / kappa_tr)
        delta = (sigma_s * R0 - 1j * lam * G[2]) / (lam ** 2 * D + sigma_a)
        M[0] += y0 * delta
        if method != "dsa":
            M[3] += y1 * G[0]
            M[1] += y1 * G[1]
            M[2] += y1 * (G[2] - 1j * lam * D * delta)
        worst = max(worst, max(abs(np.linalg.eigvals(M))))
    return worst


if __name__ == "__main__":
    print("| albedo | g | L | DSA (isotropic) | + current (P1) | + filtered current |")
    print("| --- | --- | --- | --- | --- | --- |")
    for a, g, L in [(0.99, 0.85, 3), (0.99, 0.85, 7), (0.99, 0.5, 3), (0.99, 0.0, 3),
                    (0.99, -0.5, 3), (0.99, -0.9, 3)]:
        r = [spectral_radius(a, g, L, m) for m in ("dsa", "p1", "filtered")]
        print(f"| {a} | {g} | {L} | {r[0]:.3f} | {r[1]:.3f} | {r[2]:.3f} |")
