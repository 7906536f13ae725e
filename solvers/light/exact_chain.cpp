#include "solvers/light/exact_chain.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <span>

#include "solvers/sweep/chain.h"
#include "src/core/empty_space.h"
#include "src/core/error.h"

namespace nimbus {

void add_voxels(RayGrid& g) {
    const Int3 m = g.box.shape();
    // kappa only marks the non-empty cells (the integral reads rho): a density too small for a
    // float stays non-empty.
    std::vector<float> mark(g.rho.size());
    for (size_t c = 0; c < g.rho.size(); ++c)
        mark[c] = g.rho[c] > 0 ? std::max(static_cast<float>(g.rho[c]), std::numeric_limits<float>::min()) : 0.0f;
    g.voxels = make_voxels({m[0], m[1], m[2]}, mark);
    g.voxels.origin = {g.box.lo[0], g.box.lo[1], g.box.lo[2]};
    g.voxels.domain = {g.domain[0], g.domain[1], g.domain[2]};
    const GridView v = g.voxels.view(g.periodic);
    size_t c = 0;
    for_each_cell(g.box, [&](int i, int j, int k) {
        v.voxel[v.index({i - g.box.lo[0], j - g.box.lo[1], k - g.box.lo[2]})].tally = g.rho[c++];
    });
}

namespace {

// The walk's state for the ray from pos (ray_integral's start): false if pos is outside g's cells.
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

}  // namespace

double ray_integral(RayGrid& g, const Vec3& b, const std::array<double, 3>& pos) {
    if (g.voxels.voxel.empty() && !g.rho.empty()) throw Error("ray_integral: the grid has no voxels (add_voxels)");
    PathState s;
    if (!ray_start(g, b, pos, s)) return 0.0;
    const GridView v = g.voxels.view(g.periodic);
    double sum = 0.0;
    walk_through(v, s, [&](std::int64_t idx, double len) { sum += v.voxel[idx].tally * len; });
    return sum;
}

void ray_cells(const RayGrid& g, const Box& cells, const Vec3& b, const std::array<double, 3>& start,
               std::vector<RaySegment>& out) {
    out.clear();
    // In double first: a downstream piece of a nearly horizontal ray starts dz |b_x / b_z| cells
    // away, beyond int (w_z = -1e-10 on 2 ranks: floor_to_int overflowed, and the walk ran 2^31
    // cells into memory until it failed). On a non-periodic x/y axis the cells where some
    // translate is inside the domain are c in (-hi, n - lo) (past() below): a start beyond them
    // that moves away, or not at all, has nothing to add (beyond); one far before them moves up
    // to a cell before them (the cells on the way add nothing either). Periodic axes drop whole
    // periods.
    std::array<double, 3> pos = start;
    // Whether no translate's cell on non-periodic axis a is, or will be, in the domain: the cell
    // c the walk starts in (below) lies outside (-hi, n - lo) and the ray moves away or not at all.
    const auto beyond = [&](int a) {
        const double lo = -cells.hi[a], hi = g.domain[a] - cells.lo[a];
        if (b[a] > 0) return pos[a] >= hi;        // c = floor(pos) >= hi
        if (b[a] < 0) return pos[a] <= lo + 1;    // c = ceil(pos) - 1 <= lo
        return pos[a] >= hi || pos[a] < lo + 1;   // c = floor(pos)
    };
    double skip = 0.0;
    for (int a = 0; a < 2; ++a) {
        if (g.periodic[a]) continue;
        if (beyond(a)) return;
        const double lo = -cells.hi[a], hi = g.domain[a] - cells.lo[a];
        if (pos[a] < lo - 1) skip = std::max(skip, (lo - 1 - pos[a]) / b[a]);
        if (pos[a] > hi + 1) skip = std::max(skip, (hi + 1 - pos[a]) / b[a]);
    }
    if (skip > 0.0) {
        for (int a = 0; a < 3; ++a) pos[a] += skip * b[a];
        for (int a = 0; a < 2; ++a)
            if (!g.periodic[a] && beyond(a)) return;
    }
    for (int a = 0; a < 2; ++a)
        if (g.periodic[a]) pos[a] -= g.domain[a] * std::floor(pos[a] / g.domain[a]);
    if (!(pos[2] >= g.box.lo[2] - 1 && pos[2] <= g.box.hi[2] + 1)) return;  // never in g's z range
    std::array<int, 3> c{}, step{};
    std::array<double, 3> next{}, inv{};
    for (int a = 0; a < 3; ++a) {
        c[a] = b[a] >= 0 ? floor_to_int(pos[a]) : -floor_to_int(-pos[a]) - 1;
        const double frac = std::clamp(pos[a] - c[a], 0.0, 1.0);
        inv[a] = 1.0 / std::abs(b[a]);  // +inf for b[a] = 0 (IEEE, as the walk)
        step[a] = b[a] > 0 ? 1 : -1;
        next[a] = b[a] > 0 ? (1.0 - frac) * inv[a] : (b[a] < 0 ? frac * inv[a] : inv[a]);
    }
    // Whether the walk is done after a step along axis a: out of g's z range, or on a
    // non-periodic x/y axis past the cells where any translate is inside the domain (c + i in
    // [0, n) for some i in [lo, hi): c in (-hi, n - lo)), moving away from them.
    const auto past = [&](int a) {
        if (a == 2) return c[2] < g.box.lo[2] || c[2] >= g.box.hi[2];
        if (g.periodic[a]) return false;
        return b[a] > 0 ? c[a] >= g.domain[a] - cells.lo[a] : (b[a] < 0 && c[a] <= -cells.hi[a]);
    };
    if (past(2)) return;
    double t = 0.0;
    for (;;) {
        const int a = next[0] <= next[1] ? (next[0] <= next[2] ? 0 : 2) : (next[1] <= next[2] ? 1 : 2);
        out.push_back({c, next[a] - t});
        t = next[a];
        c[a] += step[a];
        next[a] += inv[a];
        if (past(a)) return;
    }
}

namespace {

// acc[i - i0] += len * src[i + shift] for the i in [i0, i1) with i + shift in [lo, hi): one
// cell of a layer's ray for every translate in a row (src indexed by global x).
inline void add_run(double* __restrict acc, const double* __restrict src, int i0, int i1, int shift, int lo, int hi,
                    double len) {
    const int first = std::max(i0, lo - shift), last = std::min(i1, hi - shift);
    for (int i = first; i < last; ++i) acc[i - i0] += len * src[i + shift];
}

int wrap(int v, int n) { return ((v % n) + n) % n; }

}  // namespace

// Compiled for AVX-512 and AVX2 besides the baseline (the runs vectorize; dispatched once per call).
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
void integrate_layer(const RayGrid& g, const Box& cells, const Vec3& b, int k, bool downstream, double z_entry,
                     std::vector<RaySegment>& segments, double* out) {
    const int nx = cells.size(0), gy = g.box.size(1), gx = g.box.size(0);
    std::fill(out, out + static_cast<std::ptrdiff_t>(nx) * cells.size(1), 0.0);
    // The ray of translate (0, 0): every other one is it moved by (i, j).
    ray_cells(g, cells, b, piece_start(b, 0, 0, k, downstream, z_entry), segments);
    const int n0 = g.domain[0], n1 = g.domain[1];
    // Periodic offsets wrapped once per ray cell, into [0, n): a row's target is then at most one
    // period beyond (no division in the loops).
    for (RaySegment& s : segments) {
        if (g.periodic[0]) s.cell[0] = wrap(s.cell[0], n0);
        if (g.periodic[1]) s.cell[1] = wrap(s.cell[1], n1);
    }
    for (int j = cells.lo[1]; j < cells.hi[1]; ++j) {
        double* acc = out + static_cast<std::ptrdiff_t>(j - cells.lo[1]) * nx;
        for (const RaySegment& s : segments) {
            int jj = s.cell[1] + j;
            if (g.periodic[1]) jj -= jj >= n1 ? n1 : 0;
            else if (jj < 0 || jj >= n1) continue;
            const size_t row = static_cast<size_t>(s.cell[2] - g.box.lo[2]) * gy + (jj - g.box.lo[1]);
            const int lo = g.row_lo[row], hi = g.row_hi[row];
            if (lo >= hi) continue;
            const double* src = g.rho.data() + row * gx - g.box.lo[0];  // src[x] for global x
            if (g.periodic[0]) {  // i + shift in [0, 2 n0): below n0 directly, above wrapped
                add_run(acc, src, cells.lo[0], cells.hi[0], s.cell[0], lo, hi, s.len);
                add_run(acc, src, cells.lo[0], cells.hi[0], s.cell[0] - n0, lo, hi, s.len);
            } else {
                add_run(acc, src, cells.lo[0], cells.hi[0], s.cell[0], lo, hi, s.len);
            }
        }
    }
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
    std::vector<RaySegment> segments;
    const sweep::ChainStats stats = sweep::pass_down(d, dir, groups, [&](int g, sweep::ChainIO& io) {
        const bool downstream_rays = g > link.position;
        const Box& cells = boxes[static_cast<size_t>(g)];
        // This slab's piece of the rays (traced before waiting for upstream's partial sums).
        std::span<double> piece = io.out();
        if (!downstream_rays) {
            mine.resize(static_cast<size_t>(cells.cells()));
            piece = mine;
        }
        const size_t plane = static_cast<size_t>(cells.size(0)) * cells.size(1);
        for (int k = cells.lo[2]; k < cells.hi[2]; ++k) {
            double* layer = piece.data() + static_cast<size_t>(k - cells.lo[2]) * plane;
            integrate_layer(slab, cells, b, k, downstream_rays, z_entry, segments, layer);
            for (size_t c = 0; c < plane; ++c) layer[c] *= h;
        }
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
