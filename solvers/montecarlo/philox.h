// Philox-4x32-10, the counter-based random number generator of Salmon et al. 2011
// ("Parallel random numbers: as easy as 1, 2, 3", SC'11), written out here.
// A stream is a pure function of (key, counter): the photon keyed by (seed, light, photon
// index) draws the same numbers whichever rank traces it, so results do not depend on the
// rank count. Not thread-safe per object; no allocation; header-only.
#pragma once

#include <array>
#include <cstdint>

namespace nimbus::mc {

using Philox4x32 = std::array<std::uint32_t, 4>;

// One Philox-4x32-10 block: 10 rounds of the multiply-xor bijection keyed by `key`.
// Matches Random123's known-answer vectors (tested).
[[gnu::always_inline]] inline Philox4x32 philox4x32_10(Philox4x32 ctr, std::array<std::uint32_t, 2> key) {
    constexpr std::uint64_t M0 = 0xD2511F53u, M1 = 0xCD9E8D57u;
    constexpr std::uint32_t W0 = 0x9E3779B9u, W1 = 0xBB67AE85u;
    for (int round = 0; round < 10; ++round) {
        const std::uint64_t p0 = M0 * ctr[0], p1 = M1 * ctr[2];
        const auto hi0 = static_cast<std::uint32_t>(p0 >> 32), lo0 = static_cast<std::uint32_t>(p0);
        const auto hi1 = static_cast<std::uint32_t>(p1 >> 32), lo1 = static_cast<std::uint32_t>(p1);
        ctr = {hi1 ^ ctr[1] ^ key[0], lo1, hi0 ^ ctr[3] ^ key[1], lo0};
        key[0] += W0;
        key[1] += W1;
    }
    return ctr;
}

// The random stream of one path: key = seed, counter = (draw block, index lo, index hi, stream).
// uniform() returns doubles in the open interval (0, 1) with 32 random bits.
// The block after the current one is computed when the current one is taken into use, so its
// ~50-cycle dependency chain runs while the path uses the current four numbers instead of
// stalling the path when they run out (the sequence is the same).
class PathRng {
public:
    PathRng(std::uint64_t seed, std::uint32_t stream, std::uint64_t index)
        : key_{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32)},
          ctr_{0u, static_cast<std::uint32_t>(index), static_cast<std::uint32_t>(index >> 32), stream} {
        next_block_ = philox4x32_10(ctr_, key_);
    }

    [[gnu::always_inline]] double uniform() {
        if (next_ == 4) refill();
        return (static_cast<double>(block_[next_++]) + 0.5) * 0x1p-32;
    }

    // How many uniforms this stream has given: the next is word draws() % 4 of block
    // draws() / 4 (the lane kernel, trace_lanes.h, continues a path's stream from there).
    // The four words of block draws() / 4, the one the next uniform comes from.
    const Philox4x32& next_draw_block() const { return next_ == 4 ? next_block_ : block_; }

    std::uint64_t draws() const { return ctr_[0] == 0 ? 0 : (std::uint64_t{ctr_[0]} - 1) * 4 + static_cast<std::uint64_t>(next_); }

private:
    [[gnu::always_inline]] void refill() {
        block_ = next_block_;
        ++ctr_[0];
        next_block_ = philox4x32_10(ctr_, key_);
        next_ = 0;
    }
    std::array<std::uint32_t, 2> key_;
    Philox4x32 ctr_;  // counter of next_block_
    Philox4x32 block_{};
    Philox4x32 next_block_{};
    int next_ = 4;
};

}  // namespace nimbus::mc
