// e^{-tau} for tau >= 0 in straight-line code, so that loops over cells or rays vectorize
// (libm's exp is a call per element). Pure, header-only.
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>

namespace nimbus {

// 2^n e^r with n = round(-tau / ln 2), |r| <= ln2 / 2 (Cody-Waite: ln 2 in two parts), e^r by its
// Taylor series to r^12 (relative error < 3e-15 against std::exp, tests/unit/core/exp_neg_test);
// tau is clamped to 700 (e^{-700} ~ 1e-304, never 0 or a subnormal). exp_neg(0) is exactly 1.
inline double exp_neg(double tau) {
    const double x = -std::min(tau, 700.0);
    constexpr double kLog2e = 1.4426950408889634, kLn2Hi = 0.693147180369123816490,
                     kLn2Lo = 1.90821492927058770002e-10;
    constexpr double kShift =
        6755399441055744.0;  // 1.5 x 2^52: rounds to an integer in the low bits
    const double t = x * kLog2e + kShift;
    const double n = t - kShift;
    const double r = (x - n * kLn2Hi) - n * kLn2Lo;
    double q = 1.0 / 479001600.0;
    q = q * r + 1.0 / 39916800.0;
    q = q * r + 1.0 / 3628800.0;
    q = q * r + 1.0 / 362880.0;
    q = q * r + 1.0 / 40320.0;
    q = q * r + 1.0 / 5040.0;
    q = q * r + 1.0 / 720.0;
    q = q * r + 1.0 / 120.0;
    q = q * r + 1.0 / 24.0;
    q = q * r + 1.0 / 6.0;
    q = q * r + 0.5;
    q = q * r + 1.0;
    q = q * r + 1.0;
    const std::uint64_t scale = (std::bit_cast<std::uint64_t>(t) + 1023u) << 52;
    return q * std::bit_cast<double>(scale);
}

}  // namespace nimbus
