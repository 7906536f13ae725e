#include "solvers/lpm/segment_kernel.h"

namespace nimbus::lpm {

__attribute__((target_clones("arch=x86-64-v3", "default"))) void advance_rays(int n, double* __restrict L,
                                                                            const double* __restrict K,
                                                                            const double* __restrict Us,
                                                                            double* __restrict phi, double len,
                                                                            double w) {
    for (int i = 0; i < n; ++i) {
        const SegmentWeights sw = segment_weights(K[i] * len);
        const double u = Us[i] * len;
        phi[i] += w * (L[i] * sw.f1 + u * sw.f2);
        L[i] = L[i] * sw.e + u * sw.f1;
    }
}

__attribute__((target_clones("arch=x86-64-v3", "default"))) void advance_rays_vacuum(int n,
                                                                                      const double* __restrict L,
                                                                                      double* __restrict phi,
                                                                                      double w) {
    // advance_rays at tau = 0 and u = 0: phi += w (L f1 + 0), L = L e + 0 with f1 = e = 1.
    for (int i = 0; i < n; ++i) phi[i] += w * L[i];
}

}  // namespace nimbus::lpm
