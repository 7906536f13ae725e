// Sweep ordering: the one place where a direction's signs become loop bounds (STYLE: no
// copy of a loop per octant). An Octant holds the sign of each direction component; an
// AxisRange walks one axis of a box from the upwind side to the downwind side.
#pragma once

#include "src/core/box.h"
#include "src/core/vec3.h"

namespace nimbus::sweep {

struct Octant {
    Int3 s{1, 1, 1};  // +1: light moves toward increasing index along that axis

    static Octant of(const Vec3& w) {
        return {{w.x < 0 ? -1 : 1, w.y < 0 ? -1 : 1, w.z < 0 ? -1 : 1}};
    }
};

// Iterates [lo, hi) upwind-first: for (int i = r.first; i != r.end; i += r.step).
struct AxisRange {
    int first, end, step;
};

inline AxisRange upwind_range(int lo, int hi, int s) {
    return s > 0 ? AxisRange{lo, hi, 1} : AxisRange{hi - 1, lo - 1, -1};
}
inline AxisRange upwind_range(const Box& b, int axis, const Octant& o) {
    return upwind_range(b.lo[axis], b.hi[axis], o.s[axis]);
}

}  // namespace nimbus::sweep
