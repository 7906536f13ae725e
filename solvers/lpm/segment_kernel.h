// The per-segment kernel of a light propagation map (Fattal 2009 eq. 4 and 5). Pure, inline,
// no MPI, no allocation.
//
// Along a ray segment of path length s inside one cell with extinction kappa (1/m) and a
// constant unpropagated source u (W/(m³ sr), the coarse bin's U), the radiance obeys
// dL/ds = -kappa L + u, integrated exactly (eq. 4, exponential form, no step restriction):
//   L1 = L0 e^{-tau} + u s f1(tau),          tau = kappa s,
//   ∫_0^s L ds' = s ( L0 f1(tau) + u s f2(tau) ),
//   f1 = (1 - e^{-tau}) / tau,  f2 = (1 - f1) / tau   (series for small tau; f1(0)=1, f2(0)=1/2).
// The path integral is the segment's share of the cell's fluence; the medium removes exactly
// kappa ∫ L ds = L0 - L1 + u s from the ray, so depositing a kappa ∫L ds into U (eq. 5 with the
// loss computed by eq. 4 itself, as §3.3 asks) conserves energy to round-off.
#pragma once

#include <algorithm>
#include <cmath>

#include "src/core/exp_neg.h"

namespace nimbus::lpm {

// e is exp_neg's (src/core/exp_neg.h, within 3e-15 of std::exp): the segment bookkeeping below
// is exact for any value of e, so that accuracy affects the physics only, not energy conservation.
struct SegmentWeights {
    double e;   // e^{-tau}
    double f1;  // (1 - e^{-tau}) / tau
    double f2;  // (1 - f1) / tau
};

// Branch-free (selects, no jumps): below tau = 1e-3 the series are used, where 1 - e loses
// digits; e = 1 - tau f1 there so that the bookkeeping stays exact.
inline SegmentWeights segment_weights(double tau) {
    const bool small = tau < 1e-3;
    const double rt = 1.0 / std::max(tau, 1e-3);
    const double f1s = 1.0 - tau * (0.5 - tau * (1.0 / 6.0 - tau * (1.0 / 24.0)));
    const double f2s = 0.5 - tau * (1.0 / 6.0 - tau * (1.0 / 24.0 - tau * (1.0 / 120.0)));
    const double e_big = exp_neg(tau);
    const double f1b = (1.0 - e_big) * rt;
    const double f1 = small ? f1s : f1b;
    const double f2 = small ? f2s : (1.0 - f1b) * rt;
    const double e = small ? 1.0 - tau * f1s : e_big;
    return {e, f1, f2};
}

}  // namespace nimbus::lpm

namespace nimbus::lpm {

// Advances n rays of one direction through one segment each, all of the same shape (path
// length len, fluence weight w): ray i lies in cell i of K, Us, phi (pointers already offset to
// the segment's cell), L[i] its radiance. phi[i] += w ∫L ds / len. The arrays must not overlap.
// Vectorized (x86-64-v3 clone, AVX2 + FMA, chosen at run time where the CPU has it).
void advance_rays(int n, double* L, const double* K, const double* Us, double* phi, double len, double w);

// The same for rays through vacuum (kappa = 0 and Us = 0 in every cell): tau = 0, so e = f1 = 1
// and f2 = 1/2 exactly, L is unchanged and phi[i] += w L[i]: bit for bit what advance_rays
// gives there, without the exponential (88% of the cells of the default cumulus are empty).
void advance_rays_vacuum(int n, const double* L, double* phi, double w);

}  // namespace nimbus::lpm
