// Per-cell finite-volume kernel of the diffusion (P1) equation: pure functions, no MPI, no
// allocation. The driver (assemble.cpp) loops over a rank's cells and calls them.
//
// Equation (DESIGN §1; derivation in solvers/diffusion/README.md), per band, with
//   D = 1/(3 kappa_tr),  G = Q1/kappa_tr,  kappa_tr = kappa (1 - a g):
//   -∇·(D ∇U) + sigma_a U = Q0 - ∇·G                     (Max 2004 eq. 4, Q1 = (1/4π)∫Q w dw)
//   flux F = 4π (G - D ∇U)
//   Marshak, inward normal n:  U - 2D n·∇U + 2 n·G = 0    (Max 2004 eq. 7 with the same Q1)
//
// Cell-centred finite volumes on cubes of edge h; the cell balance divided by h reads
//   Σ_faces D_f (U_P - U_N) + sigma_a h² U_P = Q0 h² - h Σ_faces G_f·n_out
// Interior face between two full cells: D_f from the mean face density (kappa_tr of the two
// cells averaged; Max 2004 §2), G_f the mean of the two cell values. Face to an empty cell or
// to the outside of the domain: Marshak by ghost elimination with the full cell's D and G (the
// "non-empty one"). With U_f = (U_P+U_E)/2 and n·∇U = (U_P-U_E)/h the ghost U_E drops out:
//   diagonal += 2 D h / (4D + h),   rhs += (n·G) h² / (4D + h)
// and the face carries the outgoing flux F·n_out = 2π U_f, U_f = (4D U_P - 2h n·G)/(4D + h).
// Empty cells (kappa_tr = 0) get an identity row with zero rhs and no couplings.
// The source Q0 h² of a cell sits at its centre. The sources builder (sources.h) takes out of
// Q0 the share of a light's first scatter that lies in the sheet under a Marshak face the light
// enters by and leaves through that face directly (marshak_escape); the face's flux carries it
// (DiffusionProblem::escape_flux).
// D uses max(kappa_tr, kappa_floor): the transport mean free path is capped at half the smallest
// extent of the bounding box of the cell's piece of cloud (cloud_pieces.h; a face joins two cells
// of one piece; DiffusionOptions::max_transport_length overrides). Without the cap,
// the near-empty cells at a cloud's smooth edge (rho -> 0, D -> ∞) form near-singular floating
// patches and PFMG-PCG took 343 iterations on the 64³ cumulus. G is capped consistently,
// G = Q1 / max(kappa_tr, floor), since F = 4π(Q1 - ∇U/3)/kappa_tr (README: uncapped G gives
// negative sources in thin regions).
#pragma once

#include <array>
#include <cmath>

namespace nimbus::diffusion {

// What one face of a full cell P sees. neighbor_full: the cell across is inside the solve
// domain (or a periodic image) and has kappa_tr > 0.
struct FaceInput {
    double kappa_floor = 0.0; // 1/m, lower bound of kappa_tr in D
    bool neighbor_full = false;
    bool mirror = false;      // a reflective domain face: no net flux (DiffusionProblem::reflective)
    double kappa_tr_n = 0.0;  // kappa_tr of the neighbour (1/m), used when full
    double G_n = 0.0;         // neighbour's G component along this face's axis (W/m²/sr units of U)
};

// D's kappa: kappa_tr, or the cap's floor where kappa_tr is below it.
inline double capped_kappa(double kappa_tr, double kappa_floor) {
    return kappa_tr > kappa_floor ? kappa_tr : kappa_floor;
}

// Face of full cell P along an axis on side s (+1: high face, -1: low face); the outward normal
// is s·e_axis. Every term of the face is built on its coefficient c, the face's share of the
// diagonal (one division per face, which the row and every right-hand side share):
//   interior face  c = D_f = 1 / (3 kappa_f),  kappa_f from the mean of the two kappa_tr;
//   Marshak face   c = 2 D h / (4D + h) = 2h / (4 + 3 kappa h),  kappa = P's capped kappa_tr;
//   mirror         c = 0.
// An interior face also couples P to the neighbour with -c.
inline double face_coefficient(double kappa_tr_p, const FaceInput& nb, double h) {
    if (nb.mirror) return 0.0;  // F·n = 0: no term in the cell balance
    if (nb.neighbor_full) return 1.0 / (3.0 * capped_kappa(0.5 * (kappa_tr_p + nb.kappa_tr_n), nb.kappa_floor));
    return 2.0 * h / (4.0 + 3.0 * capped_kappa(kappa_tr_p, nb.kappa_floor) * h);
}

// The face's term of P's right-hand side, G_p being P's G component along the face's axis and
// c its face_coefficient: -h s G_f inside (G_f the mean of the two cells'), (n·G) h² / (4D + h)
// = c (3/2) kappa h (n·G) at a Marshak face (inward normal n = -s e_axis).
inline double face_rhs(double kappa_tr_p, double G_p, int s, const FaceInput& nb, double c, double h) {
    if (nb.mirror) return 0.0;
    if (nb.neighbor_full) return -h * s * 0.5 * (G_p + nb.G_n);
    return c * 1.5 * capped_kappa(kappa_tr_p, nb.kappa_floor) * h * (-s * G_p);
}

// Fluence-per-4π flux through the face, positive along +axis, from the solved U:
// interior face  phi = G_f - D_f (U_hi - U_lo)/h; Marshak face phi·n_out = U_f / 2 with
// U_f = (4D U_P - 2h n·G)/(4D + h) = c (2 U_P / h - 3 kappa n·G).
inline double face_flux(double kappa_tr_p, double G_p, double U_p, int s, const FaceInput& nb, double U_n, double c,
                        double h) {
    if (nb.mirror) return 0.0;
    if (nb.neighbor_full) return 0.5 * (G_p + nb.G_n) - c * s * (U_n - U_p) / h;
    const double U_f = c * (2.0 * U_p / h - 3.0 * capped_kappa(kappa_tr_p, nb.kappa_floor) * (-s * G_p));
    return s * 0.5 * U_f;
}

// The Langevin function coth y - 1/y, y >= 0: e^{-2 y x / h} on [-h/2, h/2] has its centroid
// at -(h/2) L(y).
inline double langevin(double y) {
    if (y < 1e-2) return y * (1.0 / 3.0 - y * y / 45.0);  // the difference cancels below
    return 1.0 / std::tanh(y) - 1.0 / y;
}

// The share of a source in a full cell that leaves through one of its Marshak faces directly,
// the source's centroid lying `offset` metres (0 <= offset <= h/2) from the centre toward the
// face: the Green's function of -D u'' + sigma_a u on the half cell between the centre (held,
// u = 0: what reaches it stays in the cell) and the face (Marshak, u + 2D u' = 0, outflow u/2).
// A unit source at distance d sends sinh(k d) / (sinh(k l) + 2 D k cosh(k l)) out through the
// face, k = sqrt(sigma_a / D), l = h/2; d / (l + 2D) without absorption, which is the linear hat
// share d/l times the h / (h + 4D) that the ghost elimination's Marshak face lets out. A source
// at the centre (offset 0, a thin cell) stays; one at the face of a thick cell mostly leaves.
inline double marshak_escape(double offset, double D, double sigma_a, double h) {
    const double l = 0.5 * h;
    if (!(offset > 0.0)) return 0.0;
    if (offset > l) offset = l;
    const double k = std::sqrt(sigma_a / D);
    if (k * l < 1e-6) return offset / (l + 2.0 * D);
    // Both sinh and cosh over e^{k l} / 2, finite for any k l.
    const double e = std::exp(-2.0 * k * l);
    return std::exp(k * (offset - l)) * -std::expm1(-2.0 * k * offset) / (1.0 - e + 2.0 * D * k * (1.0 + e));
}

}  // namespace nimbus::diffusion
