// Bands with equal optics (sigma_t, albedo, g). A model whose transport depends on a band only
// through its optics solves or traces each group once and scales by the band's light: the
// diffusion matrix (src/physics/band_groups.h), the Monte Carlo photons and camera paths
// (solvers/montecarlo). Pure, header-only.
#pragma once

#include <vector>

#include "src/scene/scene.h"

namespace nimbus {

inline bool same_optics(const BandOptics& a, const BandOptics& b) {
    return a.sigma_t == b.sigma_t && a.albedo == b.albedo && a.g == b.g;
}

struct OpticsGroup {
    BandOptics optics;       // of the group's first band
    std::vector<int> bands;  // ascending
};

// The groups in order of their first band.
inline std::vector<OpticsGroup> group_by_optics(const std::vector<BandOptics>& bands) {
    std::vector<OpticsGroup> groups;
    for (int b = 0; b < static_cast<int>(bands.size()); ++b) {
        const BandOptics& o = bands[static_cast<size_t>(b)];
        OpticsGroup* g = nullptr;
        for (OpticsGroup& cand : groups)
            if (same_optics(cand.optics, o)) g = &cand;
        if (g) g->bands.push_back(b);
        else groups.push_back({o, {b}});
    }
    return groups;
}

}  // namespace nimbus
