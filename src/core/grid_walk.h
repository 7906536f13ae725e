// Exact traversal of a piecewise-constant grid (3-D DDA): the Monte Carlo paths
// (solvers/montecarlo) and the reference rays of the exact light pass's tests
// (solvers/light/exact_chain.h, ray_integral). Lengths
// are in cell edges (h = 1), extinction kappa in 1/cell (kappa_cells = rho sigma_t h). Between
// calls a path state is a cell plus the position inside it as fractions in [0, 1]^3, so
// rounding never accumulates from one flight to the next (each call restarts the DDA from the
// fractions), and periodic x/y wrap by changing the cell index only. The cell is kept as its
// index into the padded grid (GridView::index), so a flight needs no division to find where it
// ended (cell_of, two 64-bit divisions, runs only when a path leaves the grid). Pure kernels: no
// MPI, no allocation, header-only.
//
// Within one call the walk is the incremental DDA of Amanatides & Woo (1987): t_next[a] is the
// distance along the ray to the next cell face on axis a and grows by 1/|d_a| per crossing, so
// a cell step costs an argmin of three values, one add and one index
// step: no division, no per-axis fractions, no cell coordinates (recovered from the index when
// the flight ends).
//
// Empty-space skipping: voxel.skip is the chessboard distance (in cells) from an empty cell to
// the nearest non-empty cell or the grid's outside (0 for non-empty cells, see empty_space.h).
// All cells within distance skip - 1 are empty and inside the grid, so the walk crosses that
// whole cube in one step (in t, like a unit step). Segments in empty cells (kappa = 0) are not
// reported (nothing scatters there), unless the walk is asked for them (kEmptyCells: the Monte
// Carlo's diffuse flights with `empty_cells`): then it crosses empty cells one by one, without
// jumps, and reports each.
//
// Layout: kappa, skip and the caller's track-length accumulator are interleaved in one 16-byte
// Voxel so that a cell step, and the tally of its segment, touch one cache line (the grid does
// not fit in L2 on the default cloud; the tally used to be a second miss per step), and the grid
// carries one ghost layer (skip = outside_skip) around it, so a unit step needs no bounds test:
// stepping onto a ghost is the rare "left the grid" case. Cell indices (GridView::index, the idx
// of on_segment) are indices into this padded array.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "src/core/huge_pages.h"
#include "src/core/vec3.h"

namespace nimbus {

// One cell of the replicated grid of an optics group.
static_assert(std::numeric_limits<double>::is_iec559, "the walk relies on IEEE division by zero giving inf");

struct Voxel {
    float kappa = 0.0f;       // extinction, 1/cell
    std::uint32_t skip = 0;   // chessboard distance to the nearest non-empty cell (0 if non-empty)
    double tally = 0.0;       // the caller's per-cell double (Monte Carlo: w len of the current light;
                              // ray_integral of solvers/light/exact_chain.h: the density)
};
static_assert(sizeof(Voxel) == 16);

// skip of the ghost layer around the domain.
inline constexpr std::uint32_t outside_skip = 0xFFFFFFFFu;

// A read-only view of the padded voxel grid of one optics group. The grid may cover only a
// box of the domain (the bounding box of the non-empty cells, the whole extent along periodic
// axes): outside it everything is empty, so a path that leaves the box never comes back, and
// the walk reports the domain face that the straight path then leaves through.
struct GridView {
    std::array<int, 3> n{0, 0, 0};   // cells of the walked box
    std::array<bool, 3> periodic{false, false, false};
    Voxel* voxel = nullptr;  // (n0+2)(n1+2)(n2+2) values, x fastest, ghost layer included (not owned;
                             // the walk only reads it, the caller may tally into Voxel::tally)
    std::array<int, 3> origin{0, 0, 0};  // the box's lowest cell in domain cells
    std::array<int, 3> domain{0, 0, 0};  // the domain's cells (= n when the box is the domain)
    // Index of cell c (domain cells 0..n-1 per axis; -1 and n are the ghost layer).
    std::int64_t index(const std::array<int, 3>& c) const {
        const std::int64_t sy = n[0] + 2, sz = sy * (n[1] + 2);
        return (static_cast<std::int64_t>(c[2]) + 1) * sz + (c[1] + 1) * sy + (c[0] + 1);
    }
};

// Owns the padded voxel array of one optics group (see make_voxels in empty_space.h).
struct VoxelGrid {
    std::array<int, 3> n{0, 0, 0};
    std::vector<Voxel, HugePageAllocator<Voxel>> voxel;  // padded, as GridView::voxel
    std::array<int, 3> origin{0, 0, 0}, domain{0, 0, 0};  // as GridView
    std::int64_t padded_cells() const { return static_cast<std::int64_t>(voxel.size()); }
    GridView view(const std::array<bool, 3>& periodic) { return {n, periodic, voxel.data(), origin, domain}; }
};

struct PathState {
    std::int64_t idx = 0;                  // the cell: GridView::index of its cell in the walked box
    std::array<double, 3> frac{0, 0, 0};  // position inside the cell, [0, 1] per axis
    Vec3 d{0, 0, 1};                       // unit direction
};

// Faces of the domain: 2 * axis + (1 if the high side), e.g. 4 = bottom (-z), 5 = top (+z).
inline int face_index(int axis, bool high) { return 2 * axis + (high ? 1 : 0); }

// floor(q) as an int, for |q| < 2^31 (exact; avoids a libm call on baseline x86-64).
inline int floor_to_int(double q) {
    const int i = static_cast<int>(q);
    return q < static_cast<double>(i) ? i - 1 : i;
}

// The domain face that the straight path from s (on face `axis` of the walked box, leaving it)
// leaves the domain through: the first non-periodic face along s.d (ties keep `axis`); `cell`
// is s's cell (cell_of(g, s.idx)).
inline int domain_exit_face(const GridView& g, const PathState& s, const std::array<int, 3>& cell,
                            const double inv[3], int axis) {
    const double dir[3] = {s.d.x, s.d.y, s.d.z};
    int best = axis;
    double t_best = std::numeric_limits<double>::infinity();
    for (int a = -1; a < 3; ++a) {
        const int b = a < 0 ? axis : a;  // the box's exit axis first, so that it wins ties
        if ((a >= 0 && b == axis) || g.periodic[b] || dir[b] == 0) continue;
        const double x = g.origin[b] + cell[b] + s.frac[b];
        const double t = (dir[b] > 0 ? g.domain[b] - x : x) * inv[b];
        if (t < t_best) t_best = t, best = b;
    }
    return face_index(best, dir[best] > 0);
}

// Cell coordinates of padded index idx (the inverse of GridView::index).
inline std::array<int, 3> cell_of(const GridView& g, std::int64_t idx) {
    const std::int64_t sy = g.n[0] + 2, sz = sy * (g.n[1] + 2);
    const std::int64_t k = idx / sz, r = idx - k * sz, j = r / sy;
    return {static_cast<int>(r - j * sy) - 1, static_cast<int>(j) - 1, static_cast<int>(k) - 1};
}

// Walks s along s.d until the optical depth `tau` is used up (returns -1; s is then at the
// collision point) or the path leaves the domain (returns the face index it leaves the domain
// through; s is then where it left the walked box, beyond which all is empty).
// on_segment(cell_index, length) is called for every piece of path inside one cell, with
// the length in cells, for cells with kappa > 0 (every cell with kEmptyCells); the sum of
// kappa * length over the calls equals the optical depth travelled (Beer-Lambert along a
// piecewise-constant medium).

namespace detail {

// The walk; kExitState: on leaving the walked box, s is set and the domain face found (else it
// just returns 0: walk_through). The unit step and the jump work on local scalars: built from
// helpers (a cursor struct, a direction struct) the Monte Carlo ran 8% slower on the default
// cloud (4.19 against 4.66 × 10⁶ collisions/s, 5 alternating runs).
template <bool kExitState, bool kEmptyCells, class OnSegment>
[[gnu::always_inline]] inline int walk(const GridView& g, PathState& s, double tau, OnSegment& on_segment) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const double dir[3] = {s.d.x, s.d.y, s.d.z};
    const double adir[3] = {std::abs(dir[0]), std::abs(dir[1]), std::abs(dir[2])};
    const std::int64_t sy = g.n[0] + 2, sz = sy * (g.n[1] + 2);
    const std::int64_t stride[3] = {1, sy, sz};
    int step[3];
    std::int64_t dstep[3];
    double inv[3];
    for (int a = 0; a < 3; ++a) {
        step[a] = dir[a] >= 0 ? 1 : -1;
        dstep[a] = dir[a] >= 0 ? stride[a] : -stride[a];
        inv[a] = 1.0 / adir[a];  // IEEE: +inf for a component of 0
    }
    // Distance from the current point (t = 0) to the next face per axis: tx, ty, tz, scalars
    // throughout (kept in an array written by a variable axis, they went through memory, and
    // reading two of them back as one vector after a jump stalled on store forwarding: ~15% of
    // the samples of the exact light pass when it walked each ray).
    auto first_face = [&](int a) {
        return inv[a] == inf ? inf : (step[a] > 0 ? 1.0 - s.frac[a] : s.frac[a]) * inv[a];
    };
    double tx = first_face(0), ty = first_face(1), tz = first_face(2);
    // Fractions at distance t along the ray (t_next[a] - t is what is left of the cell on axis a).
    auto set_frac = [&](double t) {
        const double t_next[3] = {tx, ty, tz};
        for (int a = 0; a < 3; ++a) {
            if (inv[a] == inf) continue;
            const double left = (t_next[a] - t) * adir[a];
            s.frac[a] = std::min(std::max(step[a] > 0 ? 1.0 - left : left, 0.0), 1.0);
        }
    };
    double t = 0.0;
    int last = 0;  // axis of the last unit step
    std::int64_t idx = s.idx;
    for (;;) {
        // Unit steps, the hot loop: the cell known only by its index.
        Voxel v;
        for (;;) {
            v = g.voxel[idx];
            if (v.skip > 1) [[unlikely]] {
                if (!kEmptyCells || v.skip == outside_skip) break;  // else a unit step, reported below
            }
            // argmin of t_next; ties go to the higher axis. (Bitwise selects instead of the
            // compare-and-jump the compiler emits were 20% slower on the default cloud: the
            // jumps predict well enough, and the selects lengthen the step's dependency chain.)
            const bool y_le_x = !(tx < ty);
            const double m01 = y_le_x ? ty : tx;
            const bool z_le = !(m01 < tz);
            const double t_exit = z_le ? tz : m01;
            const int axis = z_le ? 2 : (y_le_x ? 1 : 0);
            if (v.kappa > 0.0f) {
                const double kappa = v.kappa;
                const double seg = t_exit - t;
                const double depth = kappa * seg;
                if (depth >= tau) {
                    const double len = tau / kappa;
                    on_segment(idx, len);
                    s.idx = idx;
                    set_frac(t + len);
                    return -1;
                }
                tau -= depth;
                on_segment(idx, seg);
            } else if constexpr (kEmptyCells) {
                on_segment(idx, t_exit - t);
            }
            t = t_exit;
            const double t_after = t_exit + inv[axis];
            tx = axis == 0 ? t_after : tx;
            ty = axis == 1 ? t_after : ty;
            tz = axis == 2 ? t_after : tz;
            idx += dstep[axis];
            last = axis;
            // A Monte Carlo path's next cell is one of these three: ask for them a step ahead
            // (the grid is L3-resident on the default cloud and each step waits for its voxel;
            // +10% collisions/s there, README "Performance"). Integer addresses: a prefetch
            // beyond the grid is harmless, a pointer there would not be.
            if constexpr (kExitState) {
                const auto base = reinterpret_cast<std::uintptr_t>(g.voxel);
                for (int a = 0; a < 3; ++a)
                    __builtin_prefetch(reinterpret_cast<const void*>(
                        base + static_cast<std::uintptr_t>(idx + dstep[a]) * sizeof(Voxel)));
            }
        }
        if (v.skip == outside_skip) {
            // The last unit step crossed the face of the grid on axis `last`: leave or wrap.
            const int a = last;
            if (!g.periodic[a]) {
                if constexpr (!kExitState) return 0;
                s.idx = idx - dstep[a];  // back to the last cell inside
                set_frac(t);
                s.frac[a] = step[a] > 0 ? 1.0 : 0.0;
                return domain_exit_face(g, s, cell_of(g, s.idx), inv, a);
            }
            idx -= step[a] * g.n[a] * stride[a];  // the same row's cell on the far side
            continue;
        }
        // Across the empty cube of half-width e = skip - 1 around this cell in one step, in
        // t: the cube's exit face on axis a is e cells beyond t_next[a]. The path leaves it
        // through the nearest (axis `exit`, at t_exit) into the cell `skip` cells on; on the
        // other axes it crosses every face up to t_exit (at most e, the cube's own). The cube
        // lies inside the grid, so only the exit axis can reach the ghost layer, which the
        // unit loop then handles as any other step onto it.
        const int e = static_cast<int>(v.skip) - 1;
        const double cx = tx + e * inv[0], cy = ty + e * inv[1], cz = tz + e * inv[2];  // inf stays inf
        const int exit = cx < cy ? (cx < cz ? 0 : 2) : (cy < cz ? 1 : 2);
        const double t_exit = exit == 0 ? cx : (exit == 1 ? cy : cz);
        auto cross = [&](int a, double& tn) {
            if (a == exit || !(tn <= t_exit)) return;
            const int crossed = std::min(floor_to_int((t_exit - tn) * adir[a]) + 1, e);
            tn += crossed * inv[a];
            idx += crossed * dstep[a];
        };
        cross(0, tx);
        cross(1, ty);
        cross(2, tz);
        t = t_exit;
        const double t_after = t_exit + inv[exit];
        tx = exit == 0 ? t_after : tx;
        ty = exit == 1 ? t_after : ty;
        tz = exit == 2 ? t_after : tz;
        idx += (e + 1) * dstep[exit];
        last = exit;
    }
}


}  // namespace detail

// kEmptyCells: on_segment is called for the empty cells too (length, no optical depth), which
// the walk then crosses one by one.
template <bool kEmptyCells = false, class OnSegment>
[[gnu::always_inline]] inline int walk_optical_depth(const GridView& g, PathState& s, double tau,
                                                     OnSegment&& on_segment) {
    return detail::walk<true, kEmptyCells>(g, s, tau, on_segment);
}

// The walk of a ray that runs until it leaves the walked box (no optical depth to use up),
// when nothing about where it left is needed: one ray's integral (exact_chain.h's
// ray_integral, the reference of the light pass's layer integrals). Calls on_segment as
// walk_optical_depth does; leaves s unspecified. Skips what a path's exit costs (the exit
// point, the cell's coordinates: two 64-bit divisions, the domain face).
template <class OnSegment>
[[gnu::always_inline]] inline void walk_through(const GridView& g, PathState& s, OnSegment&& on_segment) {
    detail::walk<false, false>(g, s, std::numeric_limits<double>::infinity(), on_segment);
}

}  // namespace nimbus
