// Field<T>: a rank's cell data on its owned box plus `ghost` layers, `ncomp` values per cell
// (components innermost, then x, y, z). Accessors take GLOBAL cell indices, so kernels can
// compute positions directly; valid indices are owned().grown(ghost()).
#pragma once

#include <cassert>
#include <cstddef>
#include <vector>

#include "src/core/box.h"

namespace nimbus {

template <class T>
class Field {
public:
    Field() = default;
    Field(const Box& owned, int ghost, int ncomp = 1, T init = T{})
        : owned_(owned), alloc_(owned.grown(ghost)), ghost_(ghost), ncomp_(ncomp) {
        sx_ = static_cast<std::ptrdiff_t>(ncomp_);
        sy_ = sx_ * alloc_.size(0);
        sz_ = sy_ * alloc_.size(1);
        data_.assign(static_cast<size_t>(sz_ * alloc_.size(2)), init);
    }

    const Box& owned() const { return owned_; }
    const Box& allocated() const { return alloc_; }
    int ghost() const { return ghost_; }
    int ncomp() const { return ncomp_; }

    std::ptrdiff_t index(int i, int j, int k, int c = 0) const {
        assert(alloc_.contains(i, j, k) && c >= 0 && c < ncomp_);
        return (k - alloc_.lo[2]) * sz_ + (j - alloc_.lo[1]) * sy_ + (i - alloc_.lo[0]) * sx_ + c;
    }
    T& operator()(int i, int j, int k, int c = 0) { return data_[index(i, j, k, c)]; }
    const T& operator()(int i, int j, int k, int c = 0) const { return data_[index(i, j, k, c)]; }

    // Strides in elements between neighbouring cells along x, y, z.
    std::ptrdiff_t stride(int axis) const { return axis == 0 ? sx_ : (axis == 1 ? sy_ : sz_); }
    T* data() { return data_.data(); }
    const T* data() const { return data_.data(); }
    size_t size() const { return data_.size(); }
    void fill(T v) { data_.assign(data_.size(), v); }

    // Owned cells copied into a dense C-order array [z][y][x][c] (for output).
    std::vector<T> owned_values() const {
        std::vector<T> out(static_cast<size_t>(owned_.cells() * ncomp_));
        copy_owned_to(out.data());
        return out;
    }
    // The same into out (owned cells x ncomp elements), converted to U (the writer's floats).
    template <class U>
    void copy_owned_to(U* out) const {
        for (int k = owned_.lo[2]; k < owned_.hi[2]; ++k)
            for (int j = owned_.lo[1]; j < owned_.hi[1]; ++j)
                for (int i = owned_.lo[0]; i < owned_.hi[0]; ++i)
                    for (int c = 0; c < ncomp_; ++c) *out++ = static_cast<U>((*this)(i, j, k, c));
    }

private:
    Box owned_{};
    Box alloc_{};
    int ghost_ = 0;
    int ncomp_ = 1;
    std::ptrdiff_t sx_ = 1, sy_ = 0, sz_ = 0;
    std::vector<T> data_;
};

// Calls fn(i, j, k) for every cell of box b, x fastest.
template <class Fn>
inline void for_each_cell(const Box& b, Fn&& fn) {
    for (int k = b.lo[2]; k < b.hi[2]; ++k)
        for (int j = b.lo[1]; j < b.hi[1]; ++j)
            for (int i = b.lo[0]; i < b.hi[0]; ++i) fn(i, j, k);
}

enum class CopyMode { pack, unpack, add };

// The cells of box b (inside f.allocated()), all components, in for_each_cell order with the
// components innermost: copied into buf (pack; buf is resized to fit), from buf (unpack), or
// added in from buf (add). Message packing of halo layers and sweep planes.
template <CopyMode kMode, class T>
inline void copy_cells(Field<T>& f, const Box& b, std::vector<T>& buf) {
    const int nc = f.ncomp();
    if constexpr (kMode == CopyMode::pack) buf.resize(static_cast<size_t>(b.cells() * nc));
    assert(buf.size() == static_cast<size_t>(b.cells() * nc));
    size_t n = 0;
    for_each_cell(b, [&](int i, int j, int k) {
        T* v = &f(i, j, k);
        for (int c = 0; c < nc; ++c, ++n) {
            if constexpr (kMode == CopyMode::pack) buf[n] = v[c];
            else if constexpr (kMode == CopyMode::unpack) v[c] = buf[n];
            else v[c] += buf[n];
        }
    });
}

}  // namespace nimbus
