#include "solvers/diffusion/solve_region.h"

#include <algorithm>
#include <cstdint>
#include <limits>

#include "solvers/diffusion/cloud_pieces.h"
#include "src/core/bounding_box.h"
#include "src/core/halo.h"

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

void exchange_rhs_halo(const DiffusionProblem& p, Field<double>& G, const Decomposition& d) {
    if (p.rhs_within.empty()) exchange_halo(G, d);
    else exchange_halo(G, d, p.rhs_within);
}

double default_transport_length(const Box& cloud, const DiffusionProblem& p) {
    const Int3 s = cloud.shape();
    double ell = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a)
        if (!p.periodic[a]) ell = std::min(ell, 0.5 * p.h * s[a]);
    return ell;
}

TransportFloor transport_floor(const Decomposition& d, const DiffusionProblem& p, const SolveRegion& r,
                               double max_transport_length) {
    TransportFloor out;
    if (max_transport_length > 0.0) {
        out.uniform = out.largest = 1.0 / max_transport_length;
        return out;
    }
    if (r.box.empty()) return out;
    CloudPieces pieces = find_cloud_pieces(d, p.kappa_tr, r.box);
    out.pieces = static_cast<int>(pieces.bounds.size());
    for (const Box& b : pieces.bounds) out.per_piece.push_back(1.0 / default_transport_length(b, p));
    out.largest = out.per_piece[static_cast<size_t>(std::max_element(pieces.cells.begin(), pieces.cells.end()) -
                                                    pieces.cells.begin())];
    out.piece = std::move(pieces.index);
    return out;
}

}  // namespace nimbus::diffusion
