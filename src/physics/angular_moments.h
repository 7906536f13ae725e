// Angular moments for discrete ordinates: the Henyey-Greenstein phase function as a (delta-M
// scaled) Legendre series, and scattering by real spherical-harmonic moments on a quadrature.
// Pure functions, no MPI; returned values are owned by the caller.
//
// Legendre series (normalized to 1 over the sphere, DESIGN §1):
//   p(mu) = Σ_{l=0..L} (2l+1)/(4π) chi_l P_l(mu);  HG: chi_l = g^l.
// Delta-M (Wiscombe 1977, J. Atmos. Sci. 34, eqs. 7-13) with L: f = g^{L+1},
//   chi*_l = (g^l - f)/(1 - f), l = 0..L (chi*_0 = 1, chi*_1 = (g - f)/(1 - f));
//   the caller rescales the medium: sigma_t* = (1 - a f) sigma_t, a* = (1 - f) a / (1 - a f)
//   (delta_m_sigma_t_scale, delta_m_albedo below). Without delta-M, or for g <= 0 (no
//   forward peak), f = 0.
//
// Moments: real orthonormal spherical harmonics Y_{l,m}(Ω), polar axis z, μ = Ω_z,
// φ = atan2(Ω_y, Ω_x), no Condon-Shortley phase, ∫ Y_a Y_b dΩ = δ_ab:
//   Y_{l,0}  = sqrt((2l+1)/4π) P_l(μ)
//   Y_{l,m}  = sqrt(2) N_lm P_l^m(μ) cos(mφ),   Y_{l,-m} = sqrt(2) N_lm P_l^m(μ) sin(mφ),  m > 0,
//   N_lm = sqrt((2l+1)/4π (l-m)!/(l+m)!).
// Flattened index k = l² + l + m, (L+1)² moments. By the addition theorem
//   Σ_m Y_{l,m}(Ω) Y_{l,m}(Ω') = (2l+1)/(4π) P_l(Ω·Ω'),
// so with phi_k = Σ_n w_n Y_k(Ω_n) psi_n (d2m) and S(Ω_n) = Σ_k Y_k(Ω_n) chi_{l(k)} phi_k (m2d),
//   S(Ω_n) = Σ_n' w_n' p_L(Ω_n·Ω_n') psi_n' ≈ ∫ p(Ω_n·Ω') psi(Ω') dΩ'.
#pragma once

#include <cmath>
#include <numbers>
#include <vector>

#include "src/core/vec3.h"
#include "src/physics/quadrature.h"

namespace nimbus {

// Henyey-Greenstein in Legendre moments with optional delta-M scaling (Wiscombe 1977).
struct LegendrePhase {
    double f = 0;             // forward-peak fraction removed
    std::vector<double> chi;  // chi_0..chi_L (chi_0 = 1)
};
LegendrePhase hg_legendre(double g, int L, bool delta_m);  // |g| < 1, L >= 0

// p_L(mu) = Σ_l (2l+1)/(4π) chi_l P_l(mu), the truncated (scaled) phase function.
double legendre_phase_value(const LegendrePhase& p, double mu);

// Delta-M medium scaling for the caller: sigma_t* = scale · sigma_t, a* = delta_m_albedo.
inline double delta_m_sigma_t_scale(double a, double f) { return 1.0 - a * f; }
inline double delta_m_albedo(double a, double f) { return (1.0 - f) * a / (1.0 - a * f); }

// Legendre polynomials P_0..P_L at mu into P (resized to L+1).
void legendre_polynomials(int L, double mu, std::vector<double>& P);

// Real orthonormal spherical harmonics Y_k(Ω), k = 0..(L+1)²-1, of a unit direction into Y.
void real_spherical_harmonics(int L, const Vec3& dir, std::vector<double>& Y);

// The l = 1 harmonics are the current's components: Y_k = sqrt(3/4π) Ω_{axis(k)} for k = 1, 2, 3
// with axis y, z, x (m = -1, 0, 1 above), so a field with current F has the moments
// phi_k = sqrt(3/4π) F_{first_moment_axis(k)}. DSA's current correction maps through this.
constexpr int first_moment_axis(int k) { return k % 3; }  // k = 1, 2, 3 -> 1 (y), 2 (z), 0 (x)
inline double first_moment_scale() { return std::sqrt(0.75 / std::numbers::pi); }

// Scattering by moments with REAL orthonormal spherical harmonics Y_m, m = (l, m') flattened,
// (L+1)^2 moments: phi_m = Σ_n w_n Y_m(Ω_n) psi_n (discrete-to-moment),
// S(Ω_n) = Σ_m Y_m(Ω_n) chi_{l(m)} phi_m (moment-to-discrete), which is ∫ p(Ω·Ω') psi(Ω') dΩ'.
struct MomentOperator {
    int L = 0, nmom = 1, ndir = 0;
    std::vector<int> degree;    // l of each moment
    std::vector<double> d2m;    // nmom x ndir row-major: w_n Y_m(Ω_n)
    std::vector<double> m2d;    // ndir x nmom row-major: Y_m(Ω_n)
    bool conservative = false;  // Y_m with l >= 1 orthogonalized against the constant (below)
};
//
// conservative = false (default): exactly the operator above. It conserves energy
// (Σ_n w_n S_n = chi_0 Σ_n w_n psi_n) and maps psi = 1 to S = chi_0 only when the quadrature
// integrates every Y_k with 1 <= l <= L to zero, i.e. L <= q.exact_degree (S_N: N+1, but N-1
// for S12 and S16; product P x A: min(2P-1, A-1); cube bins: 3). Beyond it a beam can scatter
// more energy than it carries (cube96 at L = 8, g = 0.85: up to +2.5%; S8 at L = 16: +17%),
// which breaks albedo-1 source iteration.
// conservative = true: every harmonic with l >= 1 is replaced by Ỹ_k = Y_k - q_k/W, q_k = Σ_n w_n
// Y_k(Ω_n), W = Σ_n w_n (Gram-Schmidt against the constant in the discrete inner product), in
// both d2m and m2d. Then psi = 1 gives S = chi_0 and energy is conserved exactly on ANY
// quadrature; the kernel stays symmetric (reciprocity). Identical to the default when the
// quadrature is exact (q_k = 0). Use it whenever L > q.exact_degree. (Neither variant keeps the
// truncated phase function positive: negative S lobes of order 1e-3 chi_0 remain.)
MomentOperator make_moment_operator(const Quadrature& q, int L, bool conservative = false);

// max_{1 <= l(k) <= L} |Σ_n w_n Y_k(Ω_n)|: how far the quadrature is from integrating the
// harmonics of degree 1..L exactly (0 up to round-off when exact).
double quadrature_moment_error(const Quadrature& q, int L);

// Reference application of the operator (for tests and small problems; drivers use their own
// loops): phi = d2m psi, then S = m2d (chi ∘ phi). psi and S have q.size() entries.
void scatter_by_moments(const MomentOperator& op, const LegendrePhase& p,
                        const std::vector<double>& psi, std::vector<double>& S);

}  // namespace nimbus
