// The row kernels of LightTransport::add_forward_peak, in vector lanes. Pure, no MPI. Compiled
// for AVX2 + FMA too, chosen at run time. Arrays must not overlap.
#pragma once

namespace nimbus {

// out[q] = T' - T = e^{-sigma_scaled tau[q]} - e^{-sigma_t tau[q]} where rho[q] is 0, and 0 where
// it is not (those cells are the caller's): forward_peak_mean's empty cells, and 0 where tau is
// 0 as there (exp_neg(0) is exactly 1).
void empty_cells_peak(int n, const double* tau, const double* rho, double sigma_t,
                      double sigma_scaled, double* out);

// One target's row over nl lights: with v = e[l] peak[l n + q],
//   sum[q] += Σ_l v,   sum[(1 + c) n + q] += Σ_l v w[3 l + c]   (c = 0, 1, 2).
void sum_peaks(int n, int nl, const double* peak, const double* e, const double* w, double* sum);

}  // namespace nimbus
