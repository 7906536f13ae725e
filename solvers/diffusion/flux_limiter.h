// Flux-limited diffusion (Levermore & Pomraning 1981), the cure for P1's flux in optically thin
// regions (README "Regularizations"). Pure functions, no MPI.
//
// P1 gives F = -(4π/(3 kappa_tr)) (∇U - 3 Q1): in a thin region (kappa_tr -> 0) the flux grows
// without bound, while a radiance field can carry at most |F| <= 4πU. The Levermore-Pomraning
// limiter replaces 1/3 by lambda(R):
//   F = -(4π lambda(R) / kappa_tr) (∇U - 3 Q1),   R = |∇U - 3 Q1| / (kappa_tr U),
//   lambda(R) = (coth R - 1/R) / R            (-> 1/3 for R -> 0, -> 1/R for R -> ∞),
// so |F| = 4π lambda R U <= 4π U. Written as the P1 equation with an effective opacity
//   kappa_eff = kappa_tr / (3 lambda)  (D = 1/(3 kappa_eff), G = Q1 / kappa_eff),
// the same assembly and solver apply; lambda comes from the previous iterates (the fixed point
// lambda = lambda(R(U(lambda))) by Anderson-accelerated Picard iteration, solve_diffusion.cpp).
// From that iterate's flux (assembled with kappa_c = max(kappa_eff, floor)):
//   |∇U - 3 Q1| = 3 kappa_c |F| / (4π)   =>   R = 3 kappa_c |F| / (4π kappa_tr U).
#pragma once

#include <cmath>

namespace nimbus::diffusion {

// Largest R used: cells with U <= 0 (or a flux at the free-streaming limit) get lambda(kMaxR)
// ~ 1e-3, which keeps the row regular when sigma_a = 0.
inline constexpr double kMaxKnudsen = 1.0e3;

inline double levermore_pomraning(double R) {
    if (R < 0.1) {  // Laurent series of coth R - 1/R (the closed form cancels for small R)
        const double r2 = R * R;
        return 1.0 / 3.0 + r2 * (-1.0 / 45.0 + r2 * (2.0 / 945.0 + r2 * (-1.0 / 4725.0 + r2 * 2.0 / 93555.0)));
    }
    if (R > 20.0) return (1.0 - 1.0 / R) / R;       // coth R = 1 to double precision
    return (1.0 / std::tanh(R) - 1.0 / R) / R;
}

// R of a cell from the previous iterate: U (W/m²/sr), |F| (W/m²), kappa_tr and the opacity
// kappa_c the flux was assembled with (1/m).
inline double knudsen_number(double U, double F_norm, double kappa_tr, double kappa_c) {
    constexpr double four_pi = 4.0 * 3.14159265358979323846;
    if (U <= 0.0) return kMaxKnudsen;
    const double R = 3.0 * kappa_c * F_norm / (four_pi * kappa_tr * U);
    return R < kMaxKnudsen ? R : kMaxKnudsen;
}

}  // namespace nimbus::diffusion
