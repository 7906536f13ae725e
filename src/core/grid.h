// Geometry of the global cell grid: cubic cells of edge h (metres), origin at the low corner.
#pragma once

#include "src/core/box.h"
#include "src/core/vec3.h"

namespace nimbus {

struct Grid {
    Int3 n{0, 0, 0};       // cells per axis
    double h = 1.0;        // cell edge, metres
    Vec3 origin{0, 0, 0};  // world position of the low corner of cell (0,0,0), metres

    Box box() const { return {{0, 0, 0}, n}; }
    std::int64_t cells() const { return box().cells(); }
    Vec3 extent() const { return {n[0] * h, n[1] * h, n[2] * h}; }
    Vec3 upper() const { return origin + extent(); }
    Vec3 center(int i, int j, int k) const {
        return {origin.x + (i + 0.5) * h, origin.y + (j + 0.5) * h, origin.z + (k + 0.5) * h};
    }
    double cell_volume() const { return h * h * h; }
};

}  // namespace nimbus
