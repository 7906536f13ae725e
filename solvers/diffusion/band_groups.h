// Grouping of bands for the diffusion solve (pure, no MPI). Bands with equal optics
// (sigma_t, albedo, g) share a matrix; within such a group, bands whose per-light
// irradiances E0 are proportional share a right-hand side: U_band = scale * U_rhs.
#pragma once

#include <vector>

#include "src/physics/lights.h"
#include "src/scene/scene.h"

namespace nimbus::diffusion {

struct BandUse {
    int band = 0;
    int rhs = 0;         // index of the right-hand side within the group
    double scale = 1.0;  // U_band = scale * U_rhs
};

struct BandGroup {
    BandOptics optics;
    std::vector<int> rhs_band;   // the band whose E0 defines each right-hand side
    std::vector<BandUse> bands;  // every band of this group
};

std::vector<BandGroup> group_bands(const std::vector<BandOptics>& bands,
                                   const std::vector<DirectionalLight>& lights);

}  // namespace nimbus::diffusion
