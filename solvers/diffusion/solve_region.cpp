#include "solvers/diffusion/solve_region.h"

#include <algorithm>
#include <cstdint>
#include <limits>

namespace nimbus::diffusion {

SolveRegion find_solve_region(const Decomposition& d, const DiffusionProblem& p, int margin) {
    constexpr int kBig = std::numeric_limits<int>::max();
    int lo[3] = {kBig, kBig, kBig}, neg_hi[3] = {kBig, kBig, kBig};  // min of -hi = -max hi
    for_each_cell(d.local(), [&](int i, int j, int k) {
        if (p.kappa_tr(i, j, k) <= 0.0) return;
        const int c[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], c[a]);
            neg_hi[a] = std::min(neg_hi[a], -(c[a] + 1));
        }
    });
    int glo[3], gneg_hi[3];
    MPI_Allreduce(lo, glo, 3, MPI_INT, MPI_MIN, d.comm());
    MPI_Allreduce(neg_hi, gneg_hi, 3, MPI_INT, MPI_MIN, d.comm());
    SolveRegion r;
    if (glo[0] == kBig) return r;  // no full cell anywhere
    for (int a = 0; a < 3; ++a) {
        if (p.periodic[a]) {
            r.cloud.lo[a] = r.box.lo[a] = 0;
            r.cloud.hi[a] = r.box.hi[a] = p.n[a];
        } else {
            r.cloud.lo[a] = glo[a];
            r.cloud.hi[a] = -gneg_hi[a];
            // In 64-bit: a margin near INT_MAX must not wrap around.
            r.box.lo[a] = static_cast<int>(std::max<std::int64_t>(0, std::int64_t{glo[a]} - margin));
            r.box.hi[a] = static_cast<int>(std::min<std::int64_t>(p.n[a], std::int64_t{r.cloud.hi[a]} + margin));
        }
    }
    return r;
}

double default_transport_length(const SolveRegion& r, const DiffusionProblem& p) {
    const Int3 s = r.cloud.shape();
    double ell = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a)
        if (!p.periodic[a]) ell = std::min(ell, 0.5 * p.h * s[a]);
    return ell;
}

}  // namespace nimbus::diffusion
