// Model `lpm`: light propagation maps (Fattal 2009), pipelined over the slab chain.
//
// Parameters ([model.lpm], src/model/options.h):
//   p              6    map directions p x p per face, uniform on the cube face. Even p: with odd p
//                       the X and Y maps have a row of exactly horizontal rays (tangent 0), which
//                       never leave a layer and, on periodic x/y, cycle until all their light is
//                       deposited (a thin periodic layer: 1.6x / 1.23x the fluence at p = 3 / 5;
//                       a plume in a periodic domain: 4.7x at p = 5). Even p errs low instead
//                       (0.83 / 0.91 / 0.95 at p = 4 / 6 / 8). Odd p on periodic x/y warns.
//   refinement     1    map rays per cell along each map axis (R x R per cell face)
//   k              1    coarse bins of the unpropagated light U: 6 k² (k divides p)
//   solution_bins  1    1: fluence only; 4: fluence and flux F (first moment, for the renderer's
//                       (3g/4π) F·ω term)
//   iterations     3    rounds of six map sweeps at most
//   epsilon     1e-3    stop when max U < epsilon x max first-scatter source
//   tail   diffusion    the light still in U at the stop: none (dropped) | geometric (the series'
//                       remainder, extrapolated) | diffusion (one P1 solve with U as its source)
//                       (tail.h)
// Output per band: fluence_diffuse = ∫ I_d dω (W/m²), flux_diffuse F with solution_bins = 4.
// Report: ctx.report.values()["lpm"]: iterations, max U per iteration, seconds per map sweep,
// energy balance (source = escaped + absorbed + remaining, W). Needs slabs along z.
#pragma once

#include <memory>

#include "src/model/model.h"
#include "src/model/options.h"

namespace nimbus {

std::unique_ptr<ScatteringModel> make_lpm_model(const LpmOptions& opt);

}  // namespace nimbus
