// Per-cell view-source kernels: the radiance a volume element adds toward the camera per unit
// length, J_b(x) in W/(m³ sr), for the render modes of Max 1995. Pure functions, no MPI.
//
//   emission, emission_absorption (Max 1995 §3 eq. 4, §4.2):  J = C kappa
//   single_unshadowed (§5 eq. 9-10):      J = kappa a Σ_l E0_l p(mu_l)
//   scattering (§6 eq. 13-14 + DESIGN §1): J = kappa a [Σ_l E0_l T_l p(mu_l) + ∫ p I_d dw'] + q
//   with ∫ p I_d dw' = fluence/(4π) + (3 g / 4π) F·w_out for P1 radiance, rebuilt from fluence
//   and F by the model's closure (diffuse_inscatter below)
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
#include "src/physics/radiance_closure.h"

namespace nimbus {

// Max 1995 eq. 4: the particle model's glow C per unit projected area gives J = C kappa.
inline double emission_source(double C, double kappa) { return C * kappa; }

// Radiance source of isotropic volume emission of `power` W/m³ (all directions): q = power / 4π.
inline double emission_radiance(double power) { return power * (0.25 / std::numbers::pi); }

// The diffuse field scattered toward w_out, ∫ p I_d dw' (DESIGN §1), U = fluence/(4π) alone
// without a flux (`has_flux` false), else from U and F by the model's closure
// (src/physics/radiance_closure.h): diffusion's own P1 radiance, U + (3g/4π) F·w_out with its F
// term limited so that it stays >= 0 wherever U >= 0 (a negative J gave negative pixels: -0.049
// against a peak of 0.089 in a QA view of a diffusion cloud), or the realizable shape of a
// transport solution's moments. Either way its mean over directions is U.
inline double diffuse_inscatter(double fluence, double g, bool has_flux, const Vec3& F, const Vec3& w_out,
                                RadianceClosure closure) {
    if (!has_flux) return fluence * (0.25 / std::numbers::pi);
    return closure_inscatter(closure, fluence, g, F, w_out);
}

}  // namespace nimbus
