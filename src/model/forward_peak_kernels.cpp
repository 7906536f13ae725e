#include "src/model/forward_peak_kernels.h"

#include "src/core/exp_neg.h"

namespace nimbus {

__attribute__((target_clones("arch=x86-64-v3", "default"))) void empty_cells_peak(
    int n, const double* __restrict tau, const double* __restrict rho, double sigma_t,
    double sigma_scaled, double* __restrict out) {
    for (int q = 0; q < n; ++q) {
        const double v = exp_neg(sigma_scaled * tau[q]) - exp_neg(sigma_t * tau[q]);
        out[q] = rho[q] > 0.0 ? 0.0 : v;
    }
}

__attribute__((target_clones("arch=x86-64-v3", "default"))) void sum_peaks(
    int n, int nl, const double* __restrict peak, const double* __restrict e,
    const double* __restrict w, double* __restrict sum) {
    double* const f = sum;
    double* const fx = f + n;
    double* const fy = fx + n;
    double* const fz = fy + n;
    for (int l = 0; l < nl; ++l) {
        if (e[l] == 0.0) continue;
        const double* const p = peak + static_cast<long>(l) * n;
        const double el = e[l], wx = e[l] * w[3 * l], wy = e[l] * w[3 * l + 1],
                     wz = e[l] * w[3 * l + 2];
        for (int q = 0; q < n; ++q) {
            f[q] += el * p[q];
            fx[q] += wx * p[q];
            fy[q] += wy * p[q];
            fz[q] += wz * p[q];
        }
    }
}

}  // namespace nimbus
