// Ray / axis-aligned box intersection (slab method). Pure, no MPI.
// For the ray x(t) = o + t d, returns the parameter interval [t0, t1] (t0 <= t1) where x(t)
// lies in the closed box [lo, hi], or false when the ray line misses it. t may be negative
// (the caller clips to t >= 0). A zero direction component constrains nothing when o lies
// between the two planes on that axis and misses otherwise.
#pragma once

#include <algorithm>
#include <limits>

#include "src/core/vec3.h"

namespace nimbus {

inline bool intersect_box(const Vec3& o, const Vec3& d, const Vec3& lo, const Vec3& hi,
                          double& t0, double& t1) {
    t0 = -std::numeric_limits<double>::infinity();
    t1 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
            if (o[a] < lo[a] || o[a] > hi[a]) return false;
            continue;
        }
        const double inv = 1.0 / d[a];
        double ta = (lo[a] - o[a]) * inv, tb = (hi[a] - o[a]) * inv;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t0 <= t1;
}

}  // namespace nimbus
