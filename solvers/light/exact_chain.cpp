#include "solvers/light/exact_chain.h"

#include <mpi.h>

#include <cmath>
#include <limits>

namespace nimbus {

double slab_ray_integral(const Field<double>& rho, const Int3& n, const std::array<bool, 3>& periodic,
                         const Vec3& b, std::array<double, 3> pos) {
    const Box& own = rho.owned();
    const int z0 = own.lo[2], z1 = own.hi[2];
    constexpr double inf = std::numeric_limits<double>::infinity();
    int cell[3], step[3];
    double tmax[3], tdelta[3];
    for (int a = 0; a < 3; ++a) {
        const double da = b[a];
        step[a] = da > 0 ? 1 : -1;
        // A point on a cell face belongs to the cell the ray moves into.
        cell[a] = da >= 0 ? static_cast<int>(std::floor(pos[a])) : static_cast<int>(std::ceil(pos[a])) - 1;
        tdelta[a] = da != 0 ? std::abs(1.0 / da) : inf;
        const double next = da > 0 ? cell[a] + 1.0 : cell[a];
        tmax[a] = da != 0 ? (next - pos[a]) / da : inf;
    }
    if (cell[2] < z0 || cell[2] >= z1) return 0.0;
    for (int a = 0; a < 2; ++a) {
        if (cell[a] >= 0 && cell[a] < n[a]) continue;
        if (!periodic[a]) return 0.0;
        cell[a] = (cell[a] % n[a] + n[a]) % n[a];
    }
    double t = 0.0, sum = 0.0;
    for (;;) {
        const int a = tmax[0] < tmax[1] ? (tmax[0] < tmax[2] ? 0 : 2) : (tmax[1] < tmax[2] ? 1 : 2);
        if (tmax[a] == inf) break;  // b == 0: cannot happen for a unit vector
        sum += rho(cell[0], cell[1], cell[2]) * (tmax[a] - t);
        t = tmax[a];
        cell[a] += step[a];
        tmax[a] += tdelta[a];
        if (a == 2) {
            if (cell[2] < z0 || cell[2] >= z1) break;
        } else if (cell[a] < 0 || cell[a] >= n[a]) {
            if (!periodic[a]) break;
            cell[a] = (cell[a] + n[a]) % n[a];
        }
    }
    return sum;
}

void exact_tau_chain(const Decomposition& d, const Field<double>& rho, double h, const DirectionalLight& light,
                     Field<double>& tau) {
    const Int3 n = d.global().hi;
    const std::array<bool, 3> periodic{d.periodic(0), d.periodic(1), d.periodic(2)};
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
            piece[p++] = slab_ray_integral(rho, n, periodic, b, pos) * h;
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
