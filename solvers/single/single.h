// Model `single`: single scattering only. Its diffuse field is zero; the renderer adds the
// exact HG single scatter of every light term using T (Max 1995 §6). The first implementation
// of the ScatteringModel interface: a scene that asks for it pays only for the light pass.
#pragma once

#include <memory>

#include "src/model/model.h"

namespace nimbus {

std::unique_ptr<ScatteringModel> make_single_model();

}  // namespace nimbus
