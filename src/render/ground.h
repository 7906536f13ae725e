// The ground background: a Lambertian plane at z = grid.origin.z (the domain's bottom),
// infinite in x and y, lit by the directional lights (Max 1995 Fig. 5 puts the cloud over a
// ground; the shading is Lambert's law). Radiance leaving the ground, per band:
//   L_b = (albedo_b / π) Σ_l E0_{l,b} max(0, -w_l·z) T_{l,b}(x_ground)
// T_{l,b} = 1 outside the domain's footprint (and in mode single_unshadowed); inside it,
// exp(-sigma_t,b tau_rho_l) with tau_rho_l bilinear between the cell centres of the bottom cell
// layer (k = 0), clamped to the footprint (so the ground sees the bottom layer's shadow; the
// half cell below the layer centres is not added).
// Only ranks whose box touches the bottom hold that layer: the rank owning the hit point's
// (x, y) column at k = 0 (hit point clamped into the footprint) shades a pixel; the others do
// not, so each ground pixel is shaded exactly once. Not collective.
#pragma once

#include <vector>

#include "src/core/decomposition.h"
#include "src/render/raycaster.h"

namespace nimbus {

class GroundShading {
public:
    // Throws Error when the ground needs the light pass's tau_rho and it is missing.
    GroundShading(const RenderInputs& in, const Decomposition& d);

    // False on ranks that own no part of the bottom layer (they never shade).
    bool active() const { return active_; }
    // For the ray o + t d (t > 0): if it hits the ground at a point whose column this rank
    // owns, writes the ground radiance per band into L and returns true.
    bool shade(const Vec3& o, const Vec3& d, double* L) const;

private:
    const RenderInputs& in_;
    Box owned_;
    bool active_ = false;
    bool shadows_ = false;
    std::vector<double> albedo_;  // per band
};

}  // namespace nimbus
