#include "solvers/diffusion/band_groups.h"

#include <cmath>

#include "src/scene/optics_groups.h"

namespace nimbus::diffusion {
namespace {

// E0 of `band` = scale * E0 of `ref` for every light, to round-off?
bool proportional(const std::vector<DirectionalLight>& lights, int band, int ref, double& scale) {
    double num = 0.0, den = 0.0;
    for (auto& l : lights) {
        num += band_value(l.E0, band) * band_value(l.E0, ref);
        den += band_value(l.E0, ref) * band_value(l.E0, ref);
    }
    if (den == 0.0) return false;
    scale = num / den;
    for (auto& l : lights) {
        const double e = band_value(l.E0, band), r = band_value(l.E0, ref);
        if (std::abs(e - scale * r) > 1e-12 * std::max(std::abs(e), std::abs(r))) return false;
    }
    return true;
}

}  // namespace

std::vector<BandGroup> group_bands(const std::vector<BandOptics>& bands,
                                   const std::vector<DirectionalLight>& lights) {
    std::vector<BandGroup> groups;
    for (const OpticsGroup& og : group_by_optics(bands)) {
        BandGroup g{og.optics, {}, {}};
        for (const int b : og.bands) {
            BandUse use{b, -1, 1.0};
            for (size_t r = 0; r < g.rhs_band.size() && use.rhs < 0; ++r)
                if (proportional(lights, b, g.rhs_band[r], use.scale)) use.rhs = static_cast<int>(r);
            if (use.rhs < 0) {
                use.rhs = static_cast<int>(g.rhs_band.size());
                use.scale = 1.0;
                g.rhs_band.push_back(b);
            }
            g.bands.push_back(use);
        }
        groups.push_back(std::move(g));
    }
    return groups;
}

}  // namespace nimbus::diffusion
