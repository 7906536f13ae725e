// Model `dom`: discrete ordinates for the diffuse radiance I_d (DESIGN §1), per band
//   Ω·∇I + kappa* I = kappa* a* Σ_l chi*_l (2l+1)/(4π) ∫ P_l(Ω·Ω') I dΩ' + Q*(x, Ω)
// with the delta-M scaled optics and the exact first-collision source of band_problem.h,
// on the quadrature of DomOptions (src/physics/quadrature.h), swept with the step or the diamond
// (+ fix-up) scheme on the KBA engine (transport_sweep.h) and iterated by source iteration, DSA (iteration.h) or
// GMRES on the scattering moments (gmres.h).
//
// Options (DomOptions, [model.dom]): quadrature, order, polar, azimuthal, legendre_order,
// delta_m, scheme (step | diamond), iteration (source | dsa | gmres | gmres-plain), tolerance,
// max_iterations, tile_rows, octant_overlap, reflective (specular faces), sky (first-collision
// | boundary: the sky's uniform radiance enters at the top and side faces; fluence_diffuse then
// subtracts the uncollided sky computed by one extra sweep, keeping DESIGN's meaning).
//
// Outputs per band (bands of equal optics share one solve): fluence_diffuse = Σ_n w_n I_n +
// E0 (T* - T) (W/m²) and flux_diffuse = Σ_n w_n Ω_n I_n + E0 (T* - T) w (W/m²), owned + 1
// ghost, halo-exchanged. Report values()["dom"]: quadrature, iterations and residual history
// per solve, grind time (Kripke's: ns per cell·direction per iteration, the iteration time,
// max over ranks, / (global cells · directions · iterations)) and the sweep-only grind time,
// the seconds in the sweep engine and in the moment operators (max over ranks), pipeline
// efficiency (1 - wait/sweep time), leakage per face and the energy balance, memory per cell
// (an upper bound: the moments counted on every cell, though only the cells that scatter hold
// them, transport_sweep.h).
// Collective; throws Error on every rank when an iteration does not converge.
#pragma once

#include <memory>

#include "src/model/model.h"
#include "src/model/options.h"

namespace nimbus {

std::unique_ptr<ScatteringModel> make_dom_model(const DomOptions& opt);

}  // namespace nimbus
