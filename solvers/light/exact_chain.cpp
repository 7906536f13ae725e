#include "solvers/light/exact_chain.h"

#include <mpi.h>

#include <cmath>
#include <limits>

namespace nimbus {

double ray_integral(RayGrid& g, const Vec3& b, const std::array<double, 3>& pos) {
    const GridView v = g.voxels.view(g.periodic);
    std::array<int, 3> cell{};
    PathState s;
    for (int a = 0; a < 3; ++a) {
        // A point on a cell face belongs to the cell the ray moves into.
        int c = b[a] >= 0 ? static_cast<int>(std::floor(pos[a])) : static_cast<int>(std::ceil(pos[a])) - 1;
        s.frac[static_cast<size_t>(a)] = std::clamp(pos[a] - c, 0.0, 1.0);
        if (a < 2 && (c < 0 || c >= v.domain[a])) {
            if (!v.periodic[a]) return 0.0;
            c = (c % v.domain[a] + v.domain[a]) % v.domain[a];
        }
        c -= v.origin[a];
        if (c < 0 || c >= v.n[a]) return 0.0;
        cell[static_cast<size_t>(a)] = c;
    }
    s.idx = v.index(cell);
    s.d = b;
    double sum = 0.0;
    walk_optical_depth(v, s, std::numeric_limits<double>::infinity(),
                       [&](std::int64_t idx, double len) { sum += g.rho[static_cast<size_t>(idx)] * len; });
    return sum;
}

RayGrid make_slab_grid(const Decomposition& d, const Field<double>& rho) {
    return make_ray_grid(d.local(), d.global().hi, {d.periodic(0), d.periodic(1), d.periodic(2)},
                         [&](int i, int j, int k) { return rho(i, j, k); });
}

void exact_tau_chain(const Decomposition& d, RayGrid& slab, double h, const DirectionalLight& light,
                     Field<double>& tau) {
    const Vec3 b = -normalized(light.w);  // toward the light
    const Box& own = d.local();
    // Horizontal light never crosses a z face: every rank is on its own.
    const int sz = b.z > 0 ? 1 : (b.z < 0 ? -1 : 0);
    const int upstream = sz == 0 ? MPI_PROC_NULL : d.neighbor(2, sz);
    const int downstream = sz == 0 ? MPI_PROC_NULL : d.neighbor(2, -sz);
    // The chain from this rank downstream (away from the light): whose rays cross this slab.
    std::vector<int> chain{d.rank()};
    if (sz != 0) {
        int z_coord = d.coords()[2];
        for (int c = z_coord - sz; c >= 0 && c < d.dims()[2]; c -= sz) {
            int coords[3] = {0, 0, c};
            int r = 0;
            MPI_Cart_rank(d.comm(), coords, &r);
            chain.push_back(r);
        }
    }
    // The face where rays from downstream cells enter this slab.
    const double z_entry = sz > 0 ? own.lo[2] : own.hi[2];
    std::vector<double> piece, upstream_sum;
    for (size_t q = 0; q < chain.size(); ++q) {
        const Box cells = d.box_of(chain[q]);
        piece.assign(static_cast<size_t>(cells.cells()), 0.0);
        size_t p = 0;
        for_each_cell(cells, [&](int i, int j, int k) {
            std::array<double, 3> pos{i + 0.5, j + 0.5, k + 0.5};
            if (q > 0) {  // a downstream cell: start where its ray enters this slab
                const double t = (z_entry - pos[2]) / b.z;
                for (int a = 0; a < 3; ++a) pos[a] += t * b[a];
                pos[2] = z_entry;
            }
            piece[p++] = ray_integral(slab, b, pos) * h;
        });
        upstream_sum.assign(piece.size(), 0.0);
        if (upstream != MPI_PROC_NULL)
            MPI_Recv(upstream_sum.data(), static_cast<int>(upstream_sum.size()), MPI_DOUBLE, upstream, 930,
                     d.comm(), MPI_STATUS_IGNORE);
        for (size_t c = 0; c < piece.size(); ++c) piece[c] += upstream_sum[c];
        if (q == 0) {
            p = 0;
            for_each_cell(own, [&](int i, int j, int k) { tau(i, j, k) = piece[p++]; });
        } else {
            MPI_Send(piece.data(), static_cast<int>(piece.size()), MPI_DOUBLE, downstream, 930, d.comm());
        }
    }
}

}  // namespace nimbus
