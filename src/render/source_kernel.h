// Per-cell view-source kernels: the radiance a volume element adds toward the camera per unit
// length, J_b(x) in W/(m³ sr), for the render modes of Max 1995. Pure functions, no MPI.
//
//   emission, emission_absorption (Max 1995 §3 eq. 4, §4.2):  J = C kappa
//   single_unshadowed (§5 eq. 9-10):      J = kappa a Σ_l E0_l p(mu_l)
//   scattering (§6 eq. 13-14 + DESIGN §1): J = kappa a [Σ_l E0_l T_l p(mu_l) + fluence/(4π)
//                                                        + (3 g / 4π) F·w_out] + q
//   (the F term limited so that the diffuse part stays >= 0 where U >= 0, diffuse_inscatter below)
//   (both scattering modes) q = power / 4π, the isotropic emission of the scene's volume
//   sources in the cell ([[sources]], src/scene/emission.h; 0 where rho = 0)
// with w_out the unit direction toward the camera (the radiance's travel direction, -d for a
// view ray d), mu_l = w_l · w_out, w_l the light's travel direction, p the HG phase function
// normalized to 1 over the sphere, T_l = exp(-sigma_t tau_rho_l).
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

#include "src/core/vec3.h"
#include "src/physics/phase.h"

namespace nimbus {

// Max 1995 eq. 4: the particle model's glow C per unit projected area gives J = C kappa.
inline double emission_source(double C, double kappa) { return C * kappa; }

// Radiance source of isotropic volume emission of `power` W/m³ (all directions): q = power / 4π.
inline double emission_radiance(double power) { return power * (0.25 / std::numbers::pi); }

// The P1 diffuse field scattered toward w_out (DESIGN §1): ∫ p I_d dw' = U + (3g/4π) F·w_out,
// with U = fluence/(4π). `has_flux` false drops the F term. Where P1 fails (a flux larger than
// a non-negative in-scatter allows, (3|g|/4π)|F| > U: lit edges of a thick cloud under diffusion,
// DOM's truncated moments) the F term is scaled down to that bound, so the in-scatter is >= 0 in
// every direction wherever U >= 0 (a negative U stays negative) and its mean over directions stays U (a negative J used to give negative
// pixels: -0.049 against a peak of 0.089 in a QA view of a diffusion cloud).
inline double diffuse_inscatter(double fluence, double g, bool has_flux, const Vec3& F,
                                const Vec3& w_out) {
    constexpr double inv_4pi = 0.25 / std::numbers::pi;
    const double U = fluence * inv_4pi;
    if (!has_flux) return U;
    const double amplitude = 3.0 * std::abs(g) * inv_4pi * norm(F), limit = std::max(U, 0.0);
    const double scale = amplitude > limit ? limit / amplitude : 1.0;
    return U + scale * 3.0 * g * inv_4pi * dot(F, w_out);
}

}  // namespace nimbus
