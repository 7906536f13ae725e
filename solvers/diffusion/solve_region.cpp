#include "solvers/diffusion/solve_region.h"

#include <algorithm>
#include <cstdint>
#include <limits>

#include "src/core/bounding_box.h"

namespace nimbus::diffusion {

SolveRegion find_solve_region(const Decomposition& d, const DiffusionProblem& p, int margin) {
    SolveRegion r;
    r.cloud = bounding_box(d, [&](int i, int j, int k) { return p.kappa_tr(i, j, k) > 0.0; });
    if (r.cloud.empty()) return SolveRegion{};  // no full cell anywhere
    r.box = r.cloud;
    for (int a = 0; a < 3; ++a) {
        if (d.periodic(a)) continue;  // whole already
        // In 64-bit: a margin near INT_MAX must not wrap around.
        r.box.lo[a] = static_cast<int>(std::max<std::int64_t>(0, std::int64_t{r.cloud.lo[a]} - margin));
        r.box.hi[a] = static_cast<int>(std::min<std::int64_t>(p.n[a], std::int64_t{r.cloud.hi[a]} + margin));
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
