// Per-cell kernels of the discrete-ordinates sweep: pure inline functions of pointers and
// scalars (no MPI, no allocation), directions innermost and contiguous so the loops vectorize.
//
// Source of direction n of one octant in a cell (W/m³/sr):
//   S_n = Σ_l A_l P_l,n + Σ_k Y_k,n s_k
// with A_l = kappa* a* E0_l T*_l the first-collision amplitude of light term l, P_l,n its
// (scaled, truncated) phase value toward Ω_n, and s_k = kappa* a* chi_l(k) phi_k the
// scattering source moments (DESIGN §1; angular_moments.h).
//
// Step (upwind) scheme, cell of edge h (Lewis & Miller 1984 §4-4; the positive first-order
// scheme): the balance Σ_a |Ω_a|/h (psi - psi_in,a) + kappa psi = S with outgoing face
// values equal to the cell value gives
//   psi_n = (S_n + Σ_a c_a,n psi_in,a,n) / (kappa + Σ_a c_a,n),   c_a,n = |Ω_a,n| / h.
// Diamond difference with fix-up (second order, diamond_cell below) needs the outgoing FACE
// value per axis, which differs from the cell value.
//
// The moment operators are the dominant cost (25 moments at L 4 against 3-12 directions per
// octant): cell_source_n / accumulate_moments_n take the octant size as a compile-time ND so
// the direction loops unroll into registers; for_octant_size dispatches the common sizes
// (S4 3, S6 6, S8 10, cube96 12, product 8x16 16, S12 21, S16 36) and falls back to ND = 0
// (the run-time loops above) for any other size.
#pragma once

#include <algorithm>
#include <type_traits>

namespace nimbus::dom {

// S[n] for n < nd. A: nl amplitudes; P: nl x nd; Y: nmom x nd; s: nmom source moments.
inline void cell_source(int nd, int nl, int nmom, const double* A, const double* P, const double* Y,
                        const double* s, double* S) {
    for (int n = 0; n < nd; ++n) S[n] = 0.0;
    for (int l = 0; l < nl; ++l) {
        const double a = A[l];
        const double* p = P + l * nd;
        for (int n = 0; n < nd; ++n) S[n] += a * p[n];
    }
    for (int k = 0; k < nmom; ++k) {
        const double sk = s[k];
        const double* y = Y + k * nd;
        for (int n = 0; n < nd; ++n) S[n] += sk * y[n];
    }
}

// Step scheme. cx, cy, cz: |Ω_a|/h per direction; csum = cx + cy + cz; in_x/in_y/in_z: the
// upwind cells' angular fluxes (the incoming face values); psi: the result.
inline void step_cell(int nd, double kappa, const double* S, const double* cx, const double* cy,
                      const double* cz, const double* csum, const double* in_x, const double* in_y,
                      const double* in_z, double* psi) {
    for (int n = 0; n < nd; ++n)
        psi[n] = (S[n] + cx[n] * in_x[n] + cy[n] * in_y[n] + cz[n] * in_z[n]) / (kappa + csum[n]);
}

// Diamond difference with the set-to-zero negative-flux fix-up (Lewis & Miller 1984 §4-4).
// Same balance as the step scheme, Σ_a c_a (out_a - in_a) + kappa psi = S, closed by the
// diamond relation psi = (in_a + out_a)/2 on every axis:
//   psi_n = (S_n + 2 Σ_a c_a,n in_a,n) / (kappa + 2 Σ_a c_a,n),   out_a,n = 2 psi_n - in_a,n.
// Fix-up: an outgoing face value that comes out negative is set to 0 and the cell is solved
// again from the balance with that axis's diamond relation dropped (Z = the zeroed axes),
//   psi_n = (S_n + Σ_{a∈Z} c_a in_a + 2 Σ_{a∉Z} c_a in_a) / (kappa + 2 Σ_{a∉Z} c_a),
// repeated until no outgoing value is negative (at most 3 times); the balance holds exactly,
// psi >= 0 whenever S and the incoming values are. An axis with c_a = 0 couples nothing;
// its face value is set to psi. out_x/out_y/out_z: the outgoing face values (what the
// downwind cell along that axis reads as in_a). Returns the number of directions fixed up.
inline int diamond_cell(int nd, double kappa, const double* S, const double* cx, const double* cy,
                        const double* cz, const double* in_x, const double* in_y, const double* in_z,
                        double* psi, double* out_x, double* out_y, double* out_z, bool fixup) {
    int fixed = 0;
    for (int n = 0; n < nd; ++n) {
        const double c[3] = {cx[n], cy[n], cz[n]};
        const double in[3] = {in_x[n], in_y[n], in_z[n]};
        double p = (S[n] + 2.0 * (c[0] * in[0] + c[1] * in[1] + c[2] * in[2])) /
                   (kappa + 2.0 * (c[0] + c[1] + c[2]));
        double out[3];
        for (int a = 0; a < 3; ++a) out[a] = c[a] > 0.0 ? 2.0 * p - in[a] : p;
        if (fixup && (out[0] < 0.0 || out[1] < 0.0 || out[2] < 0.0)) {
            ++fixed;
            bool zero[3] = {false, false, false};
            for (int pass = 0; pass < 3; ++pass) {
                int nzero = 0;
                bool changed = false;
                for (int a = 0; a < 3; ++a) {
                    if (!zero[a] && out[a] < 0.0) zero[a] = changed = true;
                    nzero += zero[a] ? 1 : 0;
                }
                if (!changed) break;
                if (nzero == 3 && !(kappa > 0.0)) {
                    // Only reachable by round-off (kappa = 0 conserves Σ c out = Σ c in >= 0).
                    for (double& v : out) v = std::max(v, 0.0);
                    break;
                }
                double num = S[n], den = kappa;
                for (int a = 0; a < 3; ++a) {
                    num += (zero[a] ? 1.0 : 2.0) * c[a] * in[a];
                    den += zero[a] ? 0.0 : 2.0 * c[a];
                }
                p = num / den;
                for (int a = 0; a < 3; ++a) out[a] = zero[a] ? 0.0 : (c[a] > 0.0 ? 2.0 * p - in[a] : p);
            }
        }
        psi[n] = p;
        out_x[n] = out[0];
        out_y[n] = out[1];
        out_z[n] = out[2];
    }
    return fixed;
}

// Moment accumulation of one cell's octant: phi_k += Σ_n wY[k][n] psi_n.
inline void accumulate_moments(int nd, int nmom, const double* wY, const double* psi, double* phi) {
    for (int k = 0; k < nmom; ++k) {
        const double* w = wY + k * nd;
        double sum = 0.0;
        for (int n = 0; n < nd; ++n) sum += w[n] * psi[n];
        phi[k] += sum;
    }
}

// cell_source with nd = ND > 0 known at compile time (S accumulated in registers).
template <int ND>
inline void cell_source_n(int nl, int nmom, const double* A, const double* P, const double* Y,
                          const double* s, double* S) {
    double acc[ND];
    for (int n = 0; n < ND; ++n) acc[n] = 0.0;
    for (int l = 0; l < nl; ++l) {
        const double a = A[l];
        const double* p = P + l * ND;
        for (int n = 0; n < ND; ++n) acc[n] += a * p[n];
    }
    for (int k = 0; k < nmom; ++k) {
        const double sk = s[k];
        const double* y = Y + k * ND;
        for (int n = 0; n < ND; ++n) acc[n] += sk * y[n];
    }
    for (int n = 0; n < ND; ++n) S[n] = acc[n];
}

// accumulate_moments with nd = ND > 0 known at compile time (psi held in registers).
template <int ND>
inline void accumulate_moments_n(int nmom, const double* wY, const double* psi, double* phi) {
    double p[ND];
    for (int n = 0; n < ND; ++n) p[n] = psi[n];
    for (int k = 0; k < nmom; ++k) {
        const double* w = wY + k * ND;
        double sum = 0.0;
        for (int n = 0; n < ND; ++n) sum += w[n] * p[n];
        phi[k] += sum;
    }
}

// Calls f(std::integral_constant<int, ND>{}) with ND = nd for the common octant sizes, ND = 0
// (use the run-time kernels) otherwise.
template <class F>
inline void for_octant_size(int nd, F&& f) {
    switch (nd) {
        case 3: f(std::integral_constant<int, 3>{}); return;
        case 6: f(std::integral_constant<int, 6>{}); return;
        case 10: f(std::integral_constant<int, 10>{}); return;
        case 12: f(std::integral_constant<int, 12>{}); return;
        case 16: f(std::integral_constant<int, 16>{}); return;
        case 21: f(std::integral_constant<int, 21>{}); return;
        case 36: f(std::integral_constant<int, 36>{}); return;
        default: f(std::integral_constant<int, 0>{}); return;
    }
}

}  // namespace nimbus::dom
