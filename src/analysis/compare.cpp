#include "src/analysis/compare.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "src/core/error.h"

namespace nimbus {

FieldError field_error(const std::vector<double>& a, const std::vector<double>& b,
                       const std::vector<double>& density, const std::vector<double>* stderr_b,
                       const std::vector<double>* stderr_a) {
    if (a.size() != b.size() || density.size() != b.size())
        throw Error(fmt::format("compare: fields differ in size ({} and {} cells, density {})", a.size(),
                                b.size(), density.size()));
    if (stderr_b != nullptr && stderr_b->size() != b.size())
        throw Error("compare: the reference's standard error has a different size than its field");
    if (stderr_a != nullptr && stderr_a->size() != a.size())
        throw Error("compare: A's standard error has a different size than its field");
    if (stderr_b == nullptr) stderr_a = nullptr;  // z needs the reference's noise
    // Whether a run's standard error s at a cell of value v is usable (kZRelStderr).
    auto usable = [](double s, double v) { return s > 0 && s < kZRelStderr * std::abs(v); };
    FieldError e;
    double diff2 = 0.0, b2 = 0.0, max_b = 0.0, z2 = 0.0, sum_a = 0.0, sum_b = 0.0;
    std::size_t nz = 0;
    for (std::size_t c = 0; c < b.size(); ++c) {
        if (!(density[c] > 0)) continue;
        const double d = a[c] - b[c];
        diff2 += d * d;
        b2 += b[c] * b[c];
        sum_a += a[c];
        sum_b += b[c];
        e.max_abs = std::max(e.max_abs, std::abs(d));
        max_b = std::max(max_b, std::abs(b[c]));
        ++e.cells;
        if (stderr_b != nullptr && usable((*stderr_b)[c], b[c]) &&
            (stderr_a == nullptr || usable((*stderr_a)[c], a[c]))) {
            const double sa = stderr_a != nullptr ? (*stderr_a)[c] : 0.0, sb = (*stderr_b)[c];
            z2 += d * d / (sa * sa + sb * sb);
            ++nz;
        }
    }
    e.z_cells = nz;
    e.norm_b = std::sqrt(b2);
    e.abs_l2 = std::sqrt(diff2);
    if (stderr_b != nullptr) e.rms_z = nz > 0 ? std::sqrt(z2 / static_cast<double>(nz)) : 0.0;
    const bool identical = e.cells > 0 && e.max_abs == 0.0;
    constexpr double undefined = std::numeric_limits<double>::quiet_NaN();
    e.sum_ratio = identical ? 1.0 : sum_b != 0 ? sum_a / sum_b : undefined;
    if (identical) return e;  // every error 0, also over a zero reference
    if (e.cells == 0) {
        e.rel_l2 = e.max_rel = undefined;
        if (stderr_b != nullptr) e.rms_z = undefined;
        e.undefined = "no cells with density";
        return e;
    }
    if (stderr_b != nullptr && nz == 0) {
        e.rms_z = undefined;
        e.undefined = "no cell compared has a usable standard error (above 0, below half the value)";
    }
    e.rel_l2 = e.norm_b > 0 ? e.abs_l2 / e.norm_b : undefined;
    e.max_rel = max_b > 0 ? e.max_abs / max_b : undefined;
    if (!(e.norm_b > 0)) e.undefined = "the reference is zero on every cell compared";
    return e;
}

double max_rel_difference(const std::vector<double>& a, const std::vector<double>& b) {
    if (a.size() != b.size())
        throw Error(fmt::format("compare: fields differ in size ({} and {} values)", a.size(), b.size()));
    double max_diff = 0.0, max_b = 0.0;
    for (std::size_t c = 0; c < b.size(); ++c) {
        max_diff = std::max(max_diff, std::abs(a[c] - b[c]));
        max_b = std::max(max_b, std::abs(b[c]));
    }
    if (max_b > 0) return max_diff / max_b;
    return max_diff == 0 ? 0.0 : std::numeric_limits<double>::infinity();
}

ImageError image_error(const std::vector<float>& a, const std::vector<float>& b) {
    if (a.size() != b.size() || a.size() % 4 != 0)
        throw Error(fmt::format("compare: images differ in size ({} and {} values)", a.size(), b.size()));
    ImageError e;
    e.pixels = a.size() / 4;
    double diff2 = 0.0, b2 = 0.0, sum_a = 0.0, sum_b = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (i % 4 == 3) continue;
        const double d = static_cast<double>(a[i]) - b[i];
        diff2 += d * d;
        b2 += static_cast<double>(b[i]) * b[i];
        sum_a += a[i];
        sum_b += b[i];
    }
    e.mean_ratio = diff2 == 0 ? 1.0 : sum_b != 0 ? sum_a / sum_b : std::numeric_limits<double>::quiet_NaN();
    e.rmse = e.pixels > 0 ? std::sqrt(diff2 / (3.0 * static_cast<double>(e.pixels))) : 0.0;
    if (b2 > 0 || diff2 == 0) {
        e.rel_error = b2 > 0 ? std::sqrt(diff2) / std::sqrt(b2) : 0.0;
    } else {
        e.rel_error = std::numeric_limits<double>::quiet_NaN();
        e.undefined = "the reference image is black";
    }
    return e;
}

}  // namespace nimbus
