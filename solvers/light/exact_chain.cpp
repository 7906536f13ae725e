#include "solvers/light/exact_chain.h"

#include <cmath>
#include <span>

#include "solvers/sweep/chain.h"

namespace nimbus {

bool ray_start(RayGrid& g, const Vec3& b, const std::array<double, 3>& pos, PathState& s) {
    const GridView v = g.voxels.view(g.periodic);
    std::array<int, 3> cell{};
    for (int a = 0; a < 3; ++a) {
        // A point on a cell face belongs to the cell the ray moves into.
        int c = b[a] >= 0 ? floor_to_int(pos[a]) : -floor_to_int(-pos[a]) - 1;
        s.frac[static_cast<size_t>(a)] = std::clamp(pos[a] - c, 0.0, 1.0);
        if (a < 2 && (c < 0 || c >= v.domain[a])) {
            if (!v.periodic[a]) return false;
            c = (c % v.domain[a] + v.domain[a]) % v.domain[a];
        }
        c -= v.origin[a];
        if (c < 0 || c >= v.n[a]) return false;
        cell[static_cast<size_t>(a)] = c;
    }
    s.idx = v.index(cell);
    s.d = b;
    return true;
}

double ray_integral(RayGrid& g, const Vec3& b, const std::array<double, 3>& pos) {
    PathState s;
    if (!ray_start(g, b, pos, s)) return 0.0;
    const GridView v = g.voxels.view(g.periodic);
    double sum = 0.0;
    walk_through(v, s, [&](std::int64_t idx, double len) { sum += v.voxel[idx].tally * len; });
    return sum;
}

void ray_integral_pair(RayGrid& g, const Vec3& b, const std::array<double, 3>& pos_a,
                       const std::array<double, 3>& pos_b, double& integral_a, double& integral_b) {
    PathState sa, sb;
    const bool in_a = ray_start(g, b, pos_a, sa), in_b = ray_start(g, b, pos_b, sb);
    if (!in_a || !in_b) {
        integral_a = in_a ? ray_integral(g, b, pos_a) : 0.0;
        integral_b = in_b ? ray_integral(g, b, pos_b) : 0.0;
        return;
    }
    const GridView v = g.voxels.view(g.periodic);
    double sum_a = 0.0, sum_b = 0.0;
    walk_through_pair(
        v, sa, sb, [&](std::int64_t idx, double len) { sum_a += v.voxel[idx].tally * len; },
        [&](std::int64_t idx, double len) { sum_b += v.voxel[idx].tally * len; });
    integral_a = sum_a, integral_b = sum_b;
}

std::array<double, 3> piece_start(const Vec3& b, int i, int j, int k, bool downstream, double z_entry) {
    std::array<double, 3> pos{i + 0.5, j + 0.5, k + 0.5};
    if (downstream) {
        const double t = (z_entry - pos[2]) / b.z;
        for (int a = 0; a < 3; ++a) pos[a] += t * b[a];
        pos[2] = z_entry;
    }
    return pos;
}

RayGrid make_slab_grid(const Decomposition& d, const Field<double>& rho) {
    return make_ray_grid(d.local(), d.global().hi, {d.periodic(0), d.periodic(1), d.periodic(2)},
                         [&](int i, int j, int k) { return rho(i, j, k); });
}

void exact_tau_chain(const Decomposition& d, RayGrid& slab, double h, const DirectionalLight& light,
                     Field<double>& tau, double* busy_seconds) {
    const double t_start = MPI_Wtime();
    const Vec3 b = -normalized(light.w);  // toward the light
    const Box& own = d.local();
    // The partial sums travel away from the light; horizontal light never crosses a z face
    // (dir 0: every rank is on its own).
    const int dir = b.z > 0 ? -1 : (b.z < 0 ? 1 : 0);
    const sweep::ChainLink link = sweep::chain_link(d, dir);
    // Group g: the rays of the rank at chain position g, which cross the slabs of positions 0..g.
    sweep::ChainGroups groups;
    std::vector<Box> boxes;
    for (int g = 0; g < link.length; ++g) {
        boxes.push_back(d.box_of(sweep::chain_rank(d, dir, g)));
        groups.size.push_back(static_cast<size_t>(boxes.back().cells()));
        groups.last.push_back(g);
    }
    // The face where rays from downstream cells enter this slab.
    const double z_entry = b.z > 0 ? own.lo[2] : own.hi[2];
    std::vector<double> mine;
    const sweep::ChainStats stats = sweep::pass_down(d, dir, groups, [&](int g, sweep::ChainIO& io) {
        const bool downstream_rays = g > link.position;
        const Box& cells = boxes[static_cast<size_t>(g)];
        // This slab's piece of the rays (traced before waiting for upstream's partial sums).
        std::span<double> piece = io.out();
        if (!downstream_rays) {
            mine.resize(static_cast<size_t>(cells.cells()));
            piece = mine;
        }
        integrate_rays_along(
            slab, cells, b, [&](int i, int j, int k) { return piece_start(b, i, j, k, downstream_rays, z_entry); },
            [&](int, int, int, std::int64_t p, double integral) { piece[static_cast<size_t>(p)] = integral * h; });
        const std::span<const double> upstream_sum = io.in();
        for (size_t c = 0; c < upstream_sum.size(); ++c) piece[c] += upstream_sum[c];
        if (!downstream_rays) {
            size_t p = 0;
            for_each_cell(own, [&](int i, int j, int k) { tau(i, j, k) = piece[p++]; });
        }
    });
    if (busy_seconds) *busy_seconds = MPI_Wtime() - t_start - stats.wait_seconds;
}

}  // namespace nimbus
