// Grouping of bands for the diffusion solve (pure, no MPI). Bands with equal optics
// (sigma_t, albedo, g) share a matrix. Within such a group the right-hand sides are a basis of
// the bands' sources: the source of band b is sum over lights l of E0_l[b] S_l (S_l: light l's
// source at unit irradiance), so with the P1 system linear,
//   U_b = sum over right-hand sides r of scale_{b,r} U_r,  rhs r: sum over l of weight_{r,l} S_l.
// Two bases, the smaller is used:
//   by band:   one rhs per band, bands whose E0 are proportional over the lights share one;
//   by colour: one rhs per class of lights whose E0 are proportional over the group's bands
//              (the sun and a one-colour sky: 2 solves for any number of bands).
// The colour basis needs superposition; the flux-limited solve is nonlinear and asks for the
// band basis (superpose = false).
#pragma once

#include <vector>

#include "src/physics/lights.h"
#include "src/scene/scene.h"

namespace nimbus::diffusion {

struct RhsTerm {
    int rhs = 0;
    double scale = 1.0;
};

struct BandUse {
    int band = 0;
    std::vector<RhsTerm> terms;  // U_band = sum of scale * U_rhs
};

struct BandGroup {
    BandOptics optics;
    std::vector<std::vector<double>> rhs_weights;  // per rhs, per light: weight of S_l
    std::vector<BandUse> bands;                    // every band of this group
};

std::vector<BandGroup> group_bands(const std::vector<BandOptics>& bands,
                                   const std::vector<DirectionalLight>& lights, bool superpose = true);

}  // namespace nimbus::diffusion
