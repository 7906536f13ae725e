#include "src/analysis/compare.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "src/core/error.h"

namespace nimbus {

namespace {
double ratio(double num, double den) {
    if (den > 0) return num / den;
    return num == 0 ? 0.0 : std::numeric_limits<double>::infinity();
}
}  // namespace

FieldError field_error(const std::vector<double>& a, const std::vector<double>& b,
                       const std::vector<double>& density, const std::vector<double>* stderr_b) {
    if (a.size() != b.size() || density.size() != b.size())
        throw Error(fmt::format("compare: fields differ in size ({} and {} cells, density {})", a.size(),
                                b.size(), density.size()));
    if (stderr_b != nullptr && stderr_b->size() != b.size())
        throw Error("compare: the reference's standard error has a different size than its field");
    FieldError e;
    double diff2 = 0.0, b2 = 0.0, max_diff = 0.0, max_b = 0.0, z2 = 0.0;
    std::size_t nz = 0;
    for (std::size_t c = 0; c < b.size(); ++c) {
        if (!(density[c] > 0)) continue;
        const double d = a[c] - b[c];
        diff2 += d * d;
        b2 += b[c] * b[c];
        max_diff = std::max(max_diff, std::abs(d));
        max_b = std::max(max_b, std::abs(b[c]));
        ++e.cells;
        if (stderr_b != nullptr && (*stderr_b)[c] > 0) {
            const double z = d / (*stderr_b)[c];
            z2 += z * z;
            ++nz;
        }
    }
    e.norm_b = std::sqrt(b2);
    e.rel_l2 = ratio(std::sqrt(diff2), e.norm_b);
    e.max_rel = ratio(max_diff, max_b);
    if (stderr_b != nullptr) e.rms_z = nz > 0 ? std::sqrt(z2 / static_cast<double>(nz)) : 0.0;
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
    return ratio(max_diff, max_b);
}

ImageError image_error(const std::vector<float>& a, const std::vector<float>& b) {
    if (a.size() != b.size() || a.size() % 4 != 0)
        throw Error(fmt::format("compare: images differ in size ({} and {} values)", a.size(), b.size()));
    ImageError e;
    e.pixels = a.size() / 4;
    double diff2 = 0.0, b2 = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (i % 4 == 3) continue;
        const double d = static_cast<double>(a[i]) - b[i];
        diff2 += d * d;
        b2 += static_cast<double>(b[i]) * b[i];
    }
    e.rmse = e.pixels > 0 ? std::sqrt(diff2 / (3.0 * static_cast<double>(e.pixels))) : 0.0;
    e.rel_error = ratio(std::sqrt(diff2), std::sqrt(b2));
    return e;
}

}  // namespace nimbus
