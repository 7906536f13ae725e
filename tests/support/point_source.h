// The cell-averaged fluence of one uniformly emitting cell in a homogeneous pure absorber (or
// vacuum, kappa = 0): the analytic answer the Monte Carlo's emission and empty-cell tests
// compare against (tests/verification/montecarlo).
#pragma once

#include <array>
#include <cmath>
#include <numbers>

namespace nimbus::test {

// Cell-averaged uncollided fluence (W/m²) at the cell with low corner `det` (in cells) from a
// cell of power P (W) with low corner `src` in a pure absorber kappa:
//   phi = (1/h³) ∫_det dx ∫_src dy (P/h³) exp(-kappa |x-y|) / (4π |x-y|²) = P E[f(u)],
// u = x - y, whose density per axis is the triangle (h - |u_a - d_a|)/h² on [d_a - h, d_a + h]
// (the convolution of the two boxes); each half of each triangle by 6-point Gauss-Legendre.
inline double point_source_fluence(const std::array<double, 3>& src, const std::array<double, 3>& det,
                                   double h, double kappa, double P) {
    const double x[6] = {-0.9324695142031521, -0.6612093864662645, -0.2386191860831969,
                         0.2386191860831969,  0.6612093864662645,  0.9324695142031521};
    const double w[6] = {0.1713244923791704, 0.3607615730481386, 0.4679139345726910,
                         0.4679139345726910, 0.3607615730481386, 0.1713244923791704};
    double sum = 0.0, d[3];
    for (int a = 0; a < 3; ++a)
        d[a] = (det[static_cast<size_t>(a)] - src[static_cast<size_t>(a)]) * h;
    for (int s0 = 0; s0 < 2; ++s0)
        for (int s1 = 0; s1 < 2; ++s1)
            for (int s2 = 0; s2 < 2; ++s2)
                for (int i = 0; i < 6; ++i)
                    for (int j = 0; j < 6; ++j)
                        for (int k = 0; k < 6; ++k) {
                            const int side[3] = {s0, s1, s2};
                            const int idx[3] = {i, j, k};
                            double u[3], wt = 1.0;
                            for (int a = 0; a < 3; ++a) {
                                const double t = 0.5 * h * (1.0 + x[idx[a]]);  // |u - d| in [0, h]
                                u[a] = d[a] + (side[a] ? t : -t);
                                wt *= w[idx[a]] * 0.5 * h * (h - t) / (h * h);
                            }
                            const double r2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
                            const double r = std::sqrt(r2);
                            sum += wt * std::exp(-kappa * r) / (4.0 * std::numbers::pi * r2);
                        }
    return P * sum;
}

}  // namespace nimbus::test
