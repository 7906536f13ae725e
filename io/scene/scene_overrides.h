// "--set key=value" overrides applied to a parsed scene tree BEFORE it is converted to a
// Scene, so an override is checked exactly like the file (unknown keys, types, ranges).
// Not collective; no MPI.
//   key   : dotted path with optional array indices: "grid.n", "optics[1].albedo",
//           "model.montecarlo.photons". Missing tables on the way are created.
//   value : parsed as a TOML value ("[32,32,32]", "0.5", "true", "\"x\""); text that is not a
//           valid TOML value is taken as a string ("model.name=montecarlo").
// Each inserted value carries the source name "--set key=value", so any later error about it
// names the override instead of a line of the file (see toml_reader.h: where()).
#pragma once

#include <toml.hpp>

#include <string>
#include <vector>

namespace nimbus::scene_io {

// Throws nimbus::Error "<source>: --set <o>: <problem>" for a malformed override, an index out
// of range, or a path through a value that is not a table.
void apply_overrides(toml::value& root, const std::vector<std::string>& overrides,
                     const std::string& source);

}  // namespace nimbus::scene_io
