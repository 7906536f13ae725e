// Model `psf`: path-integral point-spread-function multiple scattering (Premoze et al. 2004).
// No volume solve: a Gaussian pyramid of each light term's light volume is looked up while the
// ray caster marches the view rays (psf_source.h), plus the ray caster's exact single
// scattering. It renders its own image (the ray caster with the PSF view-path source) and
// writes an equivalent fluence_diffuse for comparisons (README.md).
//
// Options ([model.psf], src/model/options.h):
//   levels       0     pyramid levels including level 0 (0 = down to <= 2 cells per axis)
//   step_growth  1.0   view-ray sample spacing / blur width of the view leg (0 = every step)
#pragma once

#include <memory>

#include "src/model/model.h"
#include "src/model/options.h"

namespace nimbus {

std::unique_ptr<ScatteringModel> make_psf_model(const PsfOptions& opt);

}  // namespace nimbus
