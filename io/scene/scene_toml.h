// Scene files (TOML) to the typed Scene, and back. Every error is one line naming the file,
// the line, the key and what is allowed, e.g.
//   scenes/x.toml:14: medium.densty: unknown key; allowed: kind, density, noise_amplitude, ...
// Overrides ("--set key=value") use dotted keys ("grid.n=[32,32,32]", "optics[1].albedo=0.5",
// "model.name=montecarlo"); the value is read as TOML, or as a string if it is not valid TOML.
#pragma once

#include <string>
#include <vector>

#include "src/scene/scene.h"

namespace nimbus {

// Not collective: every rank may call it and gets the same Scene or the same Error.
Scene load_scene_file(const std::string& path, const std::vector<std::string>& overrides = {});
Scene load_scene_string(const std::string& toml_text, const std::string& source_name,
                        const std::vector<std::string>& overrides = {});
// The built-in default scene (scenes/default.toml compiled in).
Scene default_scene(const std::vector<std::string>& overrides = {});
// Whether scene_to_toml writes each key's meaning (io/scene/key_docs.h) as a comment.
enum class TomlComments { none, meanings };
// The effective scene as TOML text that load_scene_string reads back to an equal Scene, with
// or without comments (the run's HDF5 output stores it without).
std::string scene_to_toml(const Scene& scene, TomlComments comments = TomlComments::none);

}  // namespace nimbus
