// The ground background: a Lambertian plane at z = grid.origin.z (the domain's bottom),
// infinite in x and y, lit by the directional lights (Max 1995 Fig. 5 puts the cloud over a
// ground; the shading is Lambert's law). Radiance leaving the ground, per band:
//   L_b = (albedo_b / π) Σ_l E0_{l,b} max(0, -w_l·z) T_{l,b}(x_ground)
// T_{l,b} = exp(-sigma_t,b tau_rho_l) (1 in mode single_unshadowed), tau_rho_l from the light
// pass (the optical depth per unit sigma_t from a cell centre out of the domain toward light l):
// - where the ray from the ground point q toward the light (u = -w_l) reaches the height of the
//   bottom cell layer's centres, p = q + (h/2) u_xy / u_z, if p lies in the domain's footprint
//   (or anywhere along a periodic axis, wrapped into it): bilinear between the centres of the
//   bottom cell layer (k = 0), clamped to the footprint (the half cell below the centres is
//   not added). Looking tau up at q itself put shadows (h/2) tan(zenith) too far toward the
//   light: two cells at the QA's sun 76° from the zenith;
// - else, if q is in the footprint, the ray has left it below those centres: 0;
// - else the ray from q toward the light either misses the domain (T = 1) or enters it
//   through a side face, where tau_rho is bilinear between the centres of that face's cells
//   (the domain's outer cell layer), clamped to the face.
// The bottom layer and the side faces of every light are gathered on all ranks once
// (nx ny + 4 (nx + ny) nz / 2 values per light), so a shadow continues past the footprint and
// past the columns a rank owns.
// The rank owning the hit point's (x, y) column at k = 0 (hit point clamped into the
// footprint) shades a pixel; the others do not, so each ground pixel is shaded exactly once.
// The constructor is collective (the side-face gather); shade() is not.
#pragma once

#include <array>
#include <vector>

#include "src/core/decomposition.h"
#include "src/render/raycaster.h"

namespace nimbus {

class GroundShading {
public:
    // Collective over d.comm(). Throws Error when the ground needs the light pass's tau_rho and
    // it is missing.
    GroundShading(const RenderInputs& in, const Decomposition& d);

    // False on ranks that own no part of the bottom layer (they never shade).
    bool active() const { return active_; }
    // For the ray o + t d (t > 0): if it hits the ground at a point whose column this rank
    // owns, writes the ground radiance per band into L and returns true.
    bool shade(const Vec3& o, const Vec3& d, double* L) const;
    // An upper bound of shade()'s L in band b on every rank: the unshadowed ground,
    // (albedo_b / π) Σ_l E0_{l,b} max(0, -w_l·z); 0 without a ground.
    double radiance_bound(int b) const;

private:
    // tau_rho of light l where the ray from ground point (qx, qy) (cells) toward the light
    // enters the domain through a side face; 0 when it misses the domain.
    double side_tau(size_t l, double qx, double qy) const;
    // tau_rho of light l at ground point (qx, qy) (cells; wrapped along periodic axes): the
    // rules above.
    double ground_tau(size_t l, double qx, double qy) const;

    const RenderInputs& in_;
    // side_[l][f]: tau_rho of light l on side face f (x-, x+, y-, y+), [k][tangential cell].
    std::vector<std::array<std::vector<double>, 4>> side_;
    // bottom_[l]: tau_rho of light l on the bottom cell layer (k = 0), [j][i].
    std::vector<std::vector<double>> bottom_;
    Box owned_;
    std::array<bool, 2> periodic_{false, false};  // x, y
    bool active_ = false;
    bool shadows_ = false;
    std::vector<double> albedo_;  // per band
};

}  // namespace nimbus
