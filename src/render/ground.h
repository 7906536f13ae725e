// The ground background: a Lambertian plane at z = grid.origin.z (the domain's bottom),
// infinite in x and y, lit by the directional lights (Max 1995 Fig. 5 puts the cloud over a
// ground; the shading is Lambert's law). Radiance leaving the ground, per band:
//   L_b = (albedo_b / π) Σ_l E0_{l,b} max(0, -w_l·z) T_{l,b}(x_ground)
// T_{l,b} = exp(-sigma_t,b tau_rho_l(q)) (1 in mode single_unshadowed). The light pass gives
// tau_rho_l (the optical depth per unit sigma_t out of the domain toward light l) at cell
// centres only, and a ground point q lies half a cell below the bottom layer's centres (or
// beside the domain), so the ray from q toward the light (u = -w_l) is split where it enters
// the core, the box spanned by the cell centres, [h/2, n h - h/2] per axis (unbounded along
// periodic x/y):
// - until then it runs through the outer shell (the domain's outer half cells), where it is
//   integrated EXACTLY over the piecewise-constant cells (the light pass's own medium), cell by
//   cell, up to the core or out of the domain;
// - from the point where it enters the core on, tau_rho is bilinear between the centres of the
//   outer cell layer whose centre plane that core face is (the bottom layer, or a side face's):
//   an interpolation, the point lies within those centres.
// A ray that misses the domain has T = 1; one that misses the core crosses only the shell (the
// outer half cells of the bottom, the sides and, entering a side within h/2 of the top, the top).
// Earlier versions looked tau_rho up at q itself (shadows (h/2) tan(zenith) too far toward the
// light), then at the bottom centres' height without the half cell below (a fog layer on the
// ground let e^{sigma_t rho h / (2 |w_z|)} too much light through), at a side face's entry
// height (its shadow an entry (h/2) u_z / |u_x| lower), and clamped to the face cells' centres
// where the ray reaches h/2 within half a cell of a side face (the centre's ray crosses half a
// cell more: T 0.21 instead of 0.54 beside a fog layer, a QA case).
// The outer layers of every light's tau_rho and of the density are gathered on all ranks once
// (about (lights + 1) (2 nx ny + 2 (nx + ny) nz) values), so a shadow continues past the
// footprint and past the columns a rank owns.
// The rank owning the hit point's (x, y) column at k = 0 (hit point clamped into the
// footprint) shades a pixel; the others do not, so each ground pixel is shaded exactly once.
// The constructor is collective (the gathers); shade() is not.
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

    // Values the constructor gathers on every rank for a grid of n cells per field (the bottom
    // and top layers and the four side layers; the light depths leave out the top), for the
    // memory estimate.
    static double outer_layer_values(const Int3& n);

    // One field's outer cell layers, the same on every rank.
    struct OuterLayers {
        std::vector<double> bottom;               // k = 0: [j][i]
        std::vector<double> top;                  // k = nz - 1: [j][i] (the density's only)
        std::array<std::vector<double>, 4> side;  // x-, x+, y-, y+: [k][t], t along the face
    };

private:
    // tau_rho of light l (density times metres) from ground point (qx, qy) (cells; wrapped
    // along periodic axes) toward the light: the rules above.
    double ground_tau(size_t l, double qx, double qy) const;
    // ∫ rho ds (cells) along (qx, qy, 0) + s u, s in [sa, sb], a piece of ray inside the outer
    // shell: exact over the piecewise-constant outer cells.
    double shell_integral(double qx, double qy, const Vec3& u, double sa, double sb) const;
    // The density of outer cell (i, j, k) (wrapped along periodic axes) from the gathered layers.
    double outer_rho(int i, int j, int k) const;

    const RenderInputs& in_;
    std::vector<OuterLayers> tau_;  // per light
    OuterLayers rho_;
    Box owned_;
    std::array<bool, 2> periodic_{false, false};  // x, y
    bool active_ = false;
    bool shadows_ = false;
    std::vector<double> albedo_;  // per band
};

}  // namespace nimbus
