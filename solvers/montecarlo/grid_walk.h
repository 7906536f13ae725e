// Exact traversal of a piecewise-constant grid (3-D DDA in cell-local coordinates) for the
// Monte Carlo paths. Lengths are in cell edges (h = 1), extinction kappa in 1/cell
// (kappa_cells = rho sigma_t h). A path state is a cell plus the position inside it as
// fractions in [0, 1]^3, so rounding never accumulates along a long walk, and periodic x/y
// wrap by changing the cell index only. Pure kernels: no MPI, no allocation, header-only.
//
// Empty-space skipping: skip[c] is the chessboard distance (in cells) from an empty cell to the
// nearest non-empty cell or the domain's outside (0 for non-empty cells, see empty_space.h).
// All cells within distance skip - 1 are empty and inside the domain, so the walk crosses that
// whole cube in one step. Segments in empty cells (kappa = 0) are not reported: nothing
// scatters there, and the fluence of empty cells is not estimated (it stays 0).
#pragma once

#include <algorithm>
#include <cmath>
#include <array>
#include <cstdint>
#include <limits>

#include "src/core/vec3.h"

namespace nimbus::mc {

// A read-only view of the replicated extinction grid of one optics group.
struct GridView {
    std::array<int, 3> n{0, 0, 0};
    std::array<bool, 3> periodic{false, false, false};
    const float* kappa = nullptr;  // 1/cell, x fastest, n[0]*n[1]*n[2] values
    const std::uint8_t* skip = nullptr;  // chessboard distance to non-empty cells, or null
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
    std::array<double, 3> inv{}, dir{s.d.x, s.d.y, s.d.z};
    std::array<int, 3> step{};
    for (int a = 0; a < 3; ++a) {
        step[a] = dir[a] >= 0 ? 1 : -1;
        inv[a] = dir[a] != 0 ? 1.0 / std::abs(dir[a]) : inf;
    }
    std::int64_t idx = g.index(s.cell);
    for (;;) {
        const int extra = g.skip != nullptr && g.skip[idx] > 1 ? g.skip[idx] - 1 : 0;
        std::array<double, 3> t{};
        for (int a = 0; a < 3; ++a)
            t[a] = (step[a] > 0 ? 1.0 - s.frac[a] : s.frac[a]) + extra;
        for (int a = 0; a < 3; ++a) t[a] = inv[a] == inf ? inf : t[a] * inv[a];
        const int axis = t[0] < t[1] ? (t[0] < t[2] ? 0 : 2) : (t[1] < t[2] ? 1 : 2);
        const double t_exit = t[axis];
        const double kappa = g.kappa[idx];
        if (kappa > 0.0) {
            if (kappa * t_exit >= tau) {
                const double len = tau / kappa;
                on_segment(idx, len);
                for (int a = 0; a < 3; ++a) s.frac[a] = std::clamp(s.frac[a] + len * dir[a], 0.0, 1.0);
                return -1;
            }
            tau -= kappa * t_exit;
            on_segment(idx, t_exit);
        }
        if (extra == 0) {
            for (int a = 0; a < 3; ++a)
                if (a != axis) s.frac[a] = std::clamp(s.frac[a] + t_exit * dir[a], 0.0, 1.0);
        } else {
            // Across the empty cube: the other axes may change cell too (the cube lies inside
            // the domain, so no wrap is needed).
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
        }
        s.frac[axis] = step[axis] > 0 ? 0.0 : 1.0;
        int c = s.cell[axis] + step[axis] * (extra + 1);
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
    }
}

}  // namespace nimbus::mc
