// cos(2π xi) and sin(2π xi) for the azimuth of a scattering, xi in [0, 1): a few ulp, about
// a quarter of the instructions of libm's sincos. The quadrant q and the fraction r come from
// xi exactly (4 xi - q is exact for the RNG's 33-bit uniforms), r > 1/2 is folded to 1 - r
// (swapping cos and sin), so the Taylor series run on [0, π/4] only, where the first omitted
// terms are below 5e-17 (sin, after θ^15) and 2e-18 (cos, after θ^16).
// Pure kernel, header-only.
#pragma once

#include <numbers>
#include <utility>

namespace nimbus::mc {

[[gnu::always_inline]] inline void sincos_2pi(double xi, double& c, double& s) {
    const double x = 4.0 * xi;
    const int q = static_cast<int>(x);  // quadrant, 0..3
    double r = x - q;                   // [0, 1), exact
    const bool fold = r > 0.5;
    if (fold) r = 1.0 - r;              // exact
    const double th = r * (std::numbers::pi / 2), t2 = th * th;
    double sn = th * (1.0 + t2 * (-1.0 / 6 + t2 * (1.0 / 120 + t2 * (-1.0 / 5040 + t2 * (1.0 / 362880 +
                t2 * (-1.0 / 39916800 + t2 * (1.0 / 6227020800 + t2 * (-1.0 / 1307674368000))))))));
    double cs = 1.0 + t2 * (-1.0 / 2 + t2 * (1.0 / 24 + t2 * (-1.0 / 720 + t2 * (1.0 / 40320 +
                t2 * (-1.0 / 3628800 + t2 * (1.0 / 479001600 + t2 * (-1.0 / 87178291200 +
                t2 * (1.0 / 20922789888000))))))));
    if (fold) std::swap(sn, cs);
    // angle = q π/2 + α: rotate (cos α, sin α) by q quarter turns
    switch (q & 3) {
        case 0: c = cs, s = sn; break;
        case 1: c = -sn, s = cs; break;
        case 2: c = -cs, s = -sn; break;
        default: c = sn, s = -cs; break;
    }
}

}  // namespace nimbus::mc
