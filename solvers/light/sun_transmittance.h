// The light pass: for every directional light term (sun, sky bins), the optical depth of the
// density from each cell centre back to the domain boundary against the light's travel
// direction w, tau_rho(x) = ∫ rho ds, so that T = exp(-sigma_t tau_rho) per band (DESIGN §1).
//
// Method (short characteristics on the shared sweep engine, pipelined down the slab chain):
// with m the axis of largest |w_m|, the ray reaching the centre of cell c crosses the centre
// plane of the upwind layer (one cell back along m) at a point p. Then
//   tau(c) = tau(p) + ∫_p^c rho ds,
// where the segment integral is EXACT for piecewise-constant cells (the segment's pieces in
// each cell are precomputed once per direction) and tau(p) is bilinear in the four upwind
// cell centres around p. The result is exact whenever tau is affine across those four cells:
// axis-aligned light (p is a cell centre) and any medium that is homogeneous or layered
// perpendicular to m; otherwise the only error is that interpolation (measured in tests
// against a brute-force ray march). Cost: O(cells) per light, ~10 flops per cell.
#pragma once

#include <array>
#include <vector>

#include "solvers/sweep/sweep.h"
#include "src/core/decomposition.h"
#include "src/core/report.h"
#include "src/model/model.h"
#include "src/physics/lights.h"
#include "src/scene/medium.h"

namespace nimbus {

// What compute_light_transport needs of the decomposition for `method` (sweep: slabs along z);
// throws Error on every rank alike. Run also before the costly phases (pipeline, nimbus info).
void check_light_method(const Decomposition& d, LightSpec::Method method);

// A light's rays may wrap around the periodic axes at most this often before they leave (the
// exact pass walks every wrap: at w_z = -1e-6 over periodic x/y a 12³ pass took 30 s).
inline constexpr double kMaxLightWraps = 1000.0;

// Lights must leave the domain: none may travel along periodic axes only or wrap around them
// more than kMaxLightWraps times before reaching a non-periodic face, and with periodic z
// every light must be horizontal (light leaving through the bottom would enter again at the
// top: an endless vertical stack, which neither light pass models; the slab chain cannot wrap).
// Throws Error on every rank alike; compute_light_transport checks it, and so do the pipeline's
// pre-flight and `nimbus info`.
void check_lights_leave(const Decomposition& d, const std::vector<DirectionalLight>& lights);

// Collective over d.comm(). m.rho must have its ghost layer exchanged. Times "light" into
// report. method sweep: requires slabs along z (process grid 1 x 1 x P); with periodic axes the
// segment starts from the upwind layer of the non-periodic axis the light crosses fastest (z
// when x and y are both periodic), and over periodic y from an x layer the light is swept again
// until it no longer changes (report: sweeps_per_light_max). method exact: long
// characteristics instead (see LightSpec; exact_chain.h); any decomposition; slabs along z
// pipeline the rays down the chain, other process grids replicate the density.
LightTransport compute_light_transport(const Decomposition& d, const Medium& m,
                                       const std::vector<DirectionalLight>& lights, Report& report,
                                       const sweep::SweepOptions& opt = {},
                                       LightSpec::Method method = LightSpec::Method::sweep);

// Exact ∫ rho ds from the centre of global cell (i, j, k) back to the domain boundary against w,
// by a plain cell-by-cell 3-D DDA over a full density array rho_global [z][y][x] (periodic axes
// wrap; the light must then not be parallel to them). O(n) per cell. The tests' brute-force
// reference: the exact method itself sums a layer's rays at once (exact_chain.h).
double exact_tau_rho(const std::vector<double>& rho_global, const Int3& n, double h, const Vec3& w,
                     int i, int j, int k, std::array<bool, 3> periodic = {false, false, false});

}  // namespace nimbus
