// The light still unpropagated when the LPM iteration stops (issue 6): two estimates of the
// fluence it would still add. Selected by LpmOptions::tail ("none" | "geometric" | "diffusion").
//
// geometric: the remaining power decays by rho = R_n / R_{n-1} per iteration (R = Σ V Σ_m |Ω^m| U^m,
//   R_0 = the first-scatter source); ASSUMING the fluence increment keeps its spatial shape and
//   decays by the same rho, the rest of the series is  Δφ_n (rho + rho² + ...) = Δφ_n rho/(1-rho),
//   Δφ_n = the last iteration's increment. rho is capped at kRhoMax.
// diffusion: U^m (W/(m³ sr), light that is to be propagated from the cell in coarse bin m) is the
//   source of one P1 solve (solvers/diffusion, Max 2004 eq. 4, plain P1 without delta scaling:
//   the many-times-scattered light is nearly isotropic):
//     Q0 = (1/4π) Σ_m |Ω^m| U^m,  Q1 = (1/4π) Σ_m |Ω^m| U^m ω̄^m,  G = Q1/kappa_tr,
//     kappa_tr = kappa (1 - a g),  sigma_a = kappa (1 - a);   fluence += 4π U_P1, F += F_P1.
//   All orders of scattering of U are thereby included, so no energy stays unaccounted.
// Collective over d.comm().
#pragma once

#include <vector>

#include "solvers/lpm/angular.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/core/report.h"
#include "src/core/vec3.h"
#include "src/scene/medium.h"

namespace nimbus::lpm {

inline constexpr double kRhoMax = 0.995;

// rho/(1-rho) for rho = remaining / previous_remaining, capped; 0 when nothing is left.
double geometric_tail_factor(double remaining, double previous_remaining);

// Adds factor x (fluence - previous) to fluence on the owned cells (same boxes).
void add_geometric_tail(Field<double>& fluence, const Field<double>& previous, double factor);

struct DiffusionTail {
    Field<double> fluence;  // W/m², owned + 1 ghost (halo-exchanged)
    Field<double> flux;     // W/m², 3 components, owned + 1 ghost
    int solver_iterations = 0;
    double true_residual = 0.0;
};

// Coarse-bin mean directions (1/|Ω^m|) ∫_{Ω^m} ω dω, from the nested map bins.
std::vector<Vec3> coarse_mean_directions(const Angular& ang);

// Collective. U: owned, coarse bins of ang; kappa: owned + ghost (halo-exchanged), 1/m.
// with_current false: Q1 = 0 (the isotropic part of U alone). clamp_negative: negative P1
// fluence set to 0 (the tail of a non-negative U; a DSA correction, whose source has either
// sign, must not be clamped). Throws Error when nimbus was built without the diffusion model.
DiffusionTail diffusion_tail(const Decomposition& d, const Medium& m, const BandOptics& bo, const Field<double>& U,
                             const Field<double>& kappa, const Angular& ang, Report& report, bool with_current = true,
                             bool clamp_negative = true);

}  // namespace nimbus::lpm
