// Exact traversal of a piecewise-constant grid (3-D DDA) for the Monte Carlo paths. Lengths
// are in cell edges (h = 1), extinction kappa in 1/cell (kappa_cells = rho sigma_t h). Between
// calls a path state is a cell plus the position inside it as fractions in [0, 1]^3, so
// rounding never accumulates along a long walk (each call restarts the DDA from the fractions),
// and periodic x/y wrap by changing the cell index only. Pure kernels: no MPI, no allocation,
// header-only.
//
// Within one call the walk is the incremental DDA of Amanatides & Woo (1987): t_next[a] is the
// distance along the ray to the next cell face on axis a and grows by 1/|d_a| per crossing, so
// a cell step costs one comparison chain and one add (no division, no per-axis fractions).
//
// Empty-space skipping: voxel.skip is the chessboard distance (in cells) from an empty cell to
// the nearest non-empty cell or the domain's outside (0 for non-empty cells, see
// empty_space.h). All cells within distance skip - 1 are empty and inside the domain, so the
// walk crosses that whole cube in one step. Segments in empty cells (kappa = 0) are not
// reported: nothing scatters there, and the fluence of empty cells is not estimated (it stays 0).
//
// Layout: kappa and skip are interleaved in one 8-byte Voxel so that a cell step reads one
// cache line.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "src/core/vec3.h"

namespace nimbus::mc {

// One cell of the replicated grid of an optics group.
struct Voxel {
    float kappa = 0.0f;       // extinction, 1/cell
    std::uint32_t skip = 0;   // chessboard distance to the nearest non-empty cell (0 if non-empty)
};
static_assert(sizeof(Voxel) == 8);

// A read-only view of the replicated voxel grid of one optics group.
struct GridView {
    std::array<int, 3> n{0, 0, 0};
    std::array<bool, 3> periodic{false, false, false};
    const Voxel* voxel = nullptr;  // x fastest, n[0]*n[1]*n[2] values (not owned)
    std::int64_t index(const std::array<int, 3>& c) const {
        return (static_cast<std::int64_t>(c[2]) * n[1] + c[1]) * n[0] + c[0];
    }
};

struct PathState {
    std::array<int, 3> cell{0, 0, 0};
    std::array<double, 3> frac{0, 0, 0};  // position inside the cell, [0, 1] per axis
    Vec3 d{0, 0, 1};                       // unit direction
};

// Faces of the domain: 2 * axis + (1 if the high side), e.g. 4 = bottom (-z), 5 = top (+z).
inline int face_index(int axis, bool high) { return 2 * axis + (high ? 1 : 0); }

// Walks s along s.d until the optical depth `tau` is used up (returns -1; s is then at the
// collision point) or the path leaves the domain (returns the face index it left through).
// on_segment(cell_index, length) is called for every piece of path inside one cell, with
// the length in cells, for cells with kappa > 0; the sum of kappa * length over the calls
// equals the optical depth travelled (Beer-Lambert along a piecewise-constant medium).
template <class OnSegment>
inline int walk_optical_depth(const GridView& g, PathState& s, double tau, OnSegment&& on_segment) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const double dir[3] = {s.d.x, s.d.y, s.d.z};
    const double adir[3] = {std::abs(dir[0]), std::abs(dir[1]), std::abs(dir[2])};
    const std::int64_t stride[3] = {1, g.n[0], static_cast<std::int64_t>(g.n[0]) * g.n[1]};
    int step[3];
    double inv[3], t_next[3];
    for (int a = 0; a < 3; ++a) {
        step[a] = dir[a] >= 0 ? 1 : -1;
        inv[a] = dir[a] != 0 ? 1.0 / adir[a] : inf;
    }
    // Distance from the current point (t = 0) to the next face per axis.
    auto restart = [&] {
        for (int a = 0; a < 3; ++a)
            t_next[a] = inv[a] == inf ? inf : (step[a] > 0 ? 1.0 - s.frac[a] : s.frac[a]) * inv[a];
    };
    // Fractions at distance t along the ray (t_next[a] - t is what is left of the cell on axis a).
    auto set_frac = [&](double t) {
        for (int a = 0; a < 3; ++a) {
            if (inv[a] == inf) continue;
            const double left = (t_next[a] - t) * adir[a];
            s.frac[a] = std::clamp(step[a] > 0 ? 1.0 - left : left, 0.0, 1.0);
        }
    };
    restart();
    double t = 0.0;
    std::int64_t idx = g.index(s.cell);
    for (;;) {
        const Voxel v = g.voxel[idx];
        if (v.skip > 1) {
            // Across the empty cube of half-width skip - 1 around this cell in one step; the
            // cube lies inside the domain, so only the exit axis can leave or wrap.
            set_frac(t);
            const double extra = static_cast<double>(v.skip - 1);
            double tc[3];
            for (int a = 0; a < 3; ++a)
                tc[a] = inv[a] == inf ? inf : ((step[a] > 0 ? 1.0 - s.frac[a] : s.frac[a]) + extra) * inv[a];
            const int axis = tc[0] < tc[1] ? (tc[0] < tc[2] ? 0 : 2) : (tc[1] < tc[2] ? 1 : 2);
            const double t_exit = tc[axis];
            for (int a = 0; a < 3; ++a) {
                if (a == axis) continue;
                const double q = s.frac[a] + t_exit * dir[a];
                const double fl = std::floor(q);
                int c = s.cell[a] + static_cast<int>(fl);
                double f = q - fl;
                if (c >= g.n[a]) c = g.n[a] - 1, f = 1.0;
                if (c < 0) c = 0, f = 0.0;
                s.cell[a] = c;
                s.frac[a] = f;
            }
            s.frac[axis] = step[axis] > 0 ? 0.0 : 1.0;
            int c = s.cell[axis] + step[axis] * static_cast<int>(v.skip);
            if (c < 0 || c >= g.n[axis]) {
                if (!g.periodic[axis]) {
                    s.frac[axis] = step[axis] > 0 ? 1.0 : 0.0;
                    s.cell[axis] = std::clamp(c, 0, g.n[axis] - 1);
                    return face_index(axis, step[axis] > 0);
                }
                c = c < 0 ? g.n[axis] - 1 : 0;
            }
            s.cell[axis] = c;
            idx = g.index(s.cell);
            restart();
            t = 0.0;
            continue;
        }
        const int axis = t_next[0] < t_next[1] ? (t_next[0] < t_next[2] ? 0 : 2) : (t_next[1] < t_next[2] ? 1 : 2);
        const double t_exit = t_next[axis];
        if (v.kappa > 0.0f) {
            const double kappa = v.kappa;
            const double seg = t_exit - t;
            const double depth = kappa * seg;
            if (depth >= tau) {
                const double len = tau / kappa;
                on_segment(idx, len);
                set_frac(t + len);
                return -1;
            }
            tau -= depth;
            on_segment(idx, seg);
        }
        t = t_exit;
        t_next[axis] += inv[axis];
        const int c = s.cell[axis] + step[axis];
        if (c < 0 || c >= g.n[axis]) {
            if (!g.periodic[axis]) {
                set_frac(t);
                s.frac[axis] = step[axis] > 0 ? 1.0 : 0.0;
                return face_index(axis, step[axis] > 0);
            }
            s.cell[axis] = c < 0 ? g.n[axis] - 1 : 0;
            idx = g.index(s.cell);
        } else {
            s.cell[axis] = c;
            idx += step[axis] * stride[axis];
        }
    }
}

}  // namespace nimbus::mc
