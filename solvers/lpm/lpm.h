// Model `lpm`: light propagation maps (Fattal 2009), pipelined over the slab chain.
//
// Parameters ([model.lpm], src/model/options.h):
//   p              5    map directions p x p per face (odd), uniform on the cube face
//   refinement     1    map rays per cell along each map axis (R x R per cell face)
//   k              1    coarse bins of the unpropagated light U: 6 k² (k divides p)
//   solution_bins  1    1: fluence only; 4: fluence and flux F (first moment, for the renderer's
//                       (3g/4π) F·ω term)
//   iterations     3    rounds of six map sweeps at most
//   epsilon     1e-3    stop when max U < epsilon x max first-scatter source
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
