// The model registry: the one place that maps a scene's model name to its implementation.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "src/model/model.h"
#include "src/scene/scene.h"

namespace nimbus {

// Throws Error naming the available models when spec.name is unknown or not built.
std::unique_ptr<ScatteringModel> make_model(const ModelSpec& spec);
// Names of the models this build provides.
std::vector<std::string> available_models();

}  // namespace nimbus
