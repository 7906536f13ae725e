// Discrete-ordinates quadratures on the unit sphere: directions Ω_n and solid-angle weights w_n
// with Σ_n w_n = 4π, so that ∫ f(Ω) dΩ ≈ Σ_n w_n f(Ω_n). Pure functions, no MPI; each call
// returns a fresh value (the caller owns it). Bad arguments throw nimbus::Error (one line).
//
// level_symmetric(N): the LQ_N sets (Carlson & Lathrop 1968; Lewis & Miller 1984 §4-2), N even,
//   2..16, N(N+2) directions. Per octant the cosines are mu_i, i = 1..N/2, with
//     mu_i² = mu_1² + (i-1) · 2(1 - 3 mu_1²)/(N - 2)                      (Lewis & Miller eq. 4-9)
//   and the points are (mu_i, mu_j, mu_k) with i + j + k = N/2 + 2, so mu_x²+mu_y²+mu_z² = 1;
//   mu_1 is the standard value (level_symmetric_mu1). Points equivalent under a permutation of
//   the axes share one weight (a "point weight class": 1, 1, 2, 3, 4, 5, 7, 8 classes for
//   S2..S16). The class weights solve the even-moment conditions
//     Σ_octant w x^{2a} y^{2b} z^{2c} = ∫_octant x^{2a} y^{2b} z^{2c} dΩ,  a >= b >= c,
//     2(a+b+c) <= N-2,
//   a consistent system of full rank (Householder least squares, residual checked <= 1e-12).
//   Imposing only the pure mu_z moments leaves a null space for S14/S16; the mixed moments pick
//   the unique set equal to the 16-digit LQ_N tables of current S_N codes. All weights are
//   positive; the set is invariant under every permutation and reflection of the axes and
//   integrates every polynomial of degree <= N+1 exactly, except S12 and S16 (degree <= N-1;
//   their degree-N moments are off by 3e-8 and 3e-9 relative). Order: octant-major (octant o has x < 0 if o&1, y < 0 if o&2,
//   z < 0 if o&4), the same N(N+2)/8 points in every octant.
// product_quadrature(P, A): Gauss-Legendre in mu_z (P points over [-1, 1], P even) times A equal
//   azimuths φ_j = (2j+1)π/A (Chebyshev), w = w_GL · 2π/A. Integrates polynomials in mu_z up to
//   degree 2P-1 times cos(kφ), sin(kφ) for k < A exactly: exact_degree = min(2P-1, A-1). A must be a multiple of 4 so that no
//   direction lies in a coordinate plane (the sweep needs every component non-zero).
//   Order: polar-major (mu_z ascending), then azimuth j.
// cube_face_bins(E): Max 1995 / Max 2004 cube-face bins: each face of the cube [-1,1]³ is cut
//   into E x E squares (E even); the direction is the normalized bin centre and the weight is
//   the bin's exact solid angle. With F(a,b) = atan(ab / sqrt(1 + a² + b²)), the solid angle of
//   [0,a]x[0,b] on the plane at unit distance, a rectangle [a0,a1]x[b0,b1] subtends
//     Ω = F(a1,b1) - F(a0,b1) - F(a1,b0) + F(a0,b0)   (inclusion-exclusion; F is odd in a and b).
//   E = 4 gives the 96 bins of the "cube96" option. E must be even (no bin centre on an axis
//   plane). Integrates polynomials of degree <= 3 exactly (cubic symmetry), not degree 4.
//   Order: face-major (+x, -x, +y, -y, +z, -z), then the two in-face coordinates.
#pragma once

#include <string>
#include <vector>

#include "src/core/vec3.h"
#include "src/model/options.h"

namespace nimbus {

// A discrete-ordinates quadrature on the unit sphere: directions and weights, Σ w = 4π.
struct Quadrature {
    std::string name;            // e.g. "S8 level-symmetric (80 directions)"
    std::vector<Vec3> dir;       // unit directions
    std::vector<double> weight;  // solid-angle weights (sr), sum 4π
    int exact_degree = 0;        // every polynomial in (x, y, z) of degree <= this is integrated
                                 // exactly (so are the Y_lm with l <= it: see angular_moments.h)
    int size() const { return static_cast<int>(dir.size()); }
};

Quadrature level_symmetric(int N);                        // S_N, N even 2..16: N(N+2) directions
Quadrature product_quadrature(int polar, int azimuthal);  // polar x azimuthal directions
Quadrature cube_face_bins(int per_edge = 4);              // 6 x per_edge² directions
Quadrature make_quadrature(const DomOptions& opt);        // dispatch on opt.quadrature

// Gauss-Legendre nodes x and weights w on [-1, 1] (n >= 1), ascending x; Σ w = 2.
void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w);

// The standard LQ_N first cosine mu_1 (N even, 2..16); Lewis & Miller Table 4-1 gives 7 digits
// (S8: 0.2182179 = 1/sqrt(21)), these are the full double-precision values.
double level_symmetric_mu1(int N);

}  // namespace nimbus
