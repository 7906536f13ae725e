// Index boxes: half-open ranges of global cell indices [lo, hi) per axis, x = axis 0.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>

namespace nimbus {

using Int3 = std::array<int, 3>;

struct Box {
    Int3 lo{0, 0, 0};
    Int3 hi{0, 0, 0};  // exclusive

    int size(int axis) const { return std::max(0, hi[axis] - lo[axis]); }
    Int3 shape() const { return {size(0), size(1), size(2)}; }
    std::int64_t cells() const {
        return static_cast<std::int64_t>(size(0)) * size(1) * size(2);
    }
    bool empty() const { return cells() == 0; }
    bool contains(int i, int j, int k) const {
        return i >= lo[0] && i < hi[0] && j >= lo[1] && j < hi[1] && k >= lo[2] && k < hi[2];
    }
    Box grown(int g) const {
        return {{lo[0] - g, lo[1] - g, lo[2] - g}, {hi[0] + g, hi[1] + g, hi[2] + g}};
    }
    // This box with its range along `axis` replaced by [a, b) (a layer or a slab of it).
    Box with_range(int axis, int a, int b) const {
        Box r = *this;
        r.lo[axis] = a;
        r.hi[axis] = b;
        return r;
    }
    Box intersect(const Box& o) const {
        Box r;
        for (int d = 0; d < 3; ++d) {
            r.lo[d] = std::max(lo[d], o.lo[d]);
            r.hi[d] = std::max(r.lo[d], std::min(hi[d], o.hi[d]));
        }
        return r;
    }
    bool operator==(const Box&) const = default;
};

}  // namespace nimbus
