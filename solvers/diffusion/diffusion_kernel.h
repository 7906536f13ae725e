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

// Result for one face: coupling to the neighbour (the off-diagonal entry is -coupling),
// the diagonal and rhs contributions.
struct FaceTerms {
    double coupling = 0.0;
    double diag = 0.0;
    double rhs = 0.0;
};

inline double diffusion_coefficient(double kappa_tr, double kappa_floor) {
    return 1.0 / (3.0 * (kappa_tr > kappa_floor ? kappa_tr : kappa_floor));
}

// Face of full cell P along an axis on side s (+1: high face, -1: low face). G_p is P's G
// component along that axis. The outward normal of the face is s·e_axis.
inline FaceTerms face_terms(double kappa_tr_p, double G_p, int s, const FaceInput& nb, double h) {
    FaceTerms t;
    if (nb.mirror) return t;  // F·n = 0: no term in the cell balance
    if (nb.neighbor_full) {
        const double D_f = diffusion_coefficient(0.5 * (kappa_tr_p + nb.kappa_tr_n), nb.kappa_floor);
        const double G_f = 0.5 * (G_p + nb.G_n);
        t.coupling = D_f;
        t.diag = D_f;
        t.rhs = -h * s * G_f;
    } else {
        const double D = diffusion_coefficient(kappa_tr_p, nb.kappa_floor);
        const double n_dot_G = -s * G_p;  // inward normal n = -s e_axis
        t.diag = 2.0 * D * h / (4.0 * D + h);
        t.rhs = n_dot_G * h * h / (4.0 * D + h);
    }
    return t;
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

// Fluence-per-4π flux through a face of full cell P, positive along +axis, from the solved U:
// interior face  phi = G_f - D_f (U_hi - U_lo)/h; Marshak face phi·n_out = U_f / 2.
inline double face_flux(double kappa_tr_p, double G_p, double U_p, int s, const FaceInput& nb,
                        double U_n, double h) {
    if (nb.mirror) return 0.0;
    if (nb.neighbor_full) {
        const double D_f = diffusion_coefficient(0.5 * (kappa_tr_p + nb.kappa_tr_n), nb.kappa_floor);
        const double G_f = 0.5 * (G_p + nb.G_n);
        return G_f - D_f * s * (U_n - U_p) / h;
    }
    const double D = diffusion_coefficient(kappa_tr_p, nb.kappa_floor);
    const double n_dot_G = -s * G_p;
    const double U_f = (4.0 * D * U_p - 2.0 * h * n_dot_G) / (4.0 * D + h);
    return s * 0.5 * U_f;
}

}  // namespace nimbus::diffusion
