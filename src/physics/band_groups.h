// Grouping of bands for models that are linear in their sources (pure, no MPI): the diffusion
// solve (one matrix per group) and discrete ordinates (one transport problem per group). Bands
// with equal optics (sigma_t, albedo, g) share the operator. Within such a group the right-hand
// sides are a basis of the bands' sources. A source term t is a light (strength E0_t[b], W/m²),
// a volume source (strength power_t[b], W/m³) or, for DOM's sky as boundary radiance, the sky
// (strength L[b], W/m²/sr); the source of band b is sum over terms t of strength_t[b] S_t
// (S_t: term t's source at unit strength), so with the model linear,
//   U_b = sum over right-hand sides r of scale_{b,r} U_r,  rhs r: sum over t of weight_{r,t} S_t.
// Two bases, the smaller is used:
//   by band:   one rhs per band, bands whose strengths are proportional over the terms share one;
//   by colour: one rhs per class of terms whose strengths are proportional over the group's
//              bands (the sun and a one-colour sky: 2 solves for any number of bands).
// The colour basis needs superposition; a nonlinear solve (flux-limited diffusion) asks for the
// band basis (superpose = false).
#pragma once

#include <string>
#include <vector>

#include "src/physics/lights.h"
#include "src/scene/emission.h"
#include "src/scene/scene.h"

namespace nimbus {

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
    std::vector<std::vector<double>> rhs_weights;  // per rhs, per source term: weight of S_t
    std::vector<BandUse> bands;                    // every band of this group
};

// strength[t][b]: source term t's strength in band b (term_strengths).
std::vector<BandGroup> group_bands(const std::vector<BandOptics>& bands,
                                   const std::vector<std::vector<double>>& strength, bool superpose = true);

// The source terms of a run, lights first (E0 per band) and then the volume sources (power per
// band, emission.h), each as a strength per band of the nbands bands.
std::vector<std::vector<double>> term_strengths(const std::vector<DirectionalLight>& lights,
                                                const std::vector<VolumeSource>& sources, int nbands);

// Calls f(band, scale) for each band of g that uses right-hand side rhs: U_band += scale U_rhs.
template <class F>
void for_each_use(const BandGroup& g, size_t rhs, F&& f) {
    for (const BandUse& use : g.bands)
        for (const RhsTerm& t : use.terms)
            if (static_cast<size_t>(t.rhs) == rhs) f(use.band, t.scale);
}

// The names of the bands of group g that use right-hand side rhs (bands: all bands of the run),
// in band order, for reports and messages.
std::vector<std::string> rhs_band_names(const BandGroup& g, size_t rhs, const std::vector<BandOptics>& bands);

// The names of the terms that right-hand side weights holds (non-zero weight), for reports: a
// light by its name, "sky" once for all its direction bins ("sky[...]"), a volume source as
// "sources[i]" (terms lights.size() on), and "sky" for a term past the volume sources (DOM's
// sky as boundary radiance). Each name once, in term order.
std::vector<std::string> term_names(const std::vector<double>& weights, const std::vector<DirectionalLight>& lights,
                                    size_t nsources);

}  // namespace nimbus
