// What each scene key means: one short line per key (and per table) with its unit and its
// allowed values, the text scene_to_toml writes as comments with TomlComments::meanings
// (docs/scene_reference.toml). Not collective; no MPI.
//
// A path is the key's dotted name without array indices, as a scene file nests it:
//   "title", "grid.cell_size", "optics.sigma_t", "medium.ellipsoid.radii", "sources.lo",
//   "model.diffusion.margin"; a table's own path ("grid", "optics", "model.dom") gives the
//   table's meaning.
// Every key and table scene_to_toml writes has an entry, and every entry is written by some
// scene (tests/unit/io_scene/key_docs_test.cpp): a new key needs its line in key_docs.cpp.
#pragma once

#include <string_view>
#include <vector>

namespace nimbus {

struct KeyDoc {
    std::string_view path;     // "grid.cell_size"
    std::string_view meaning;  // "cell edge length, in grid.unit (> 0)"
};

// Every documented key and table, in the order of a written scene file.
const std::vector<KeyDoc>& scene_key_docs();

// The meaning of one path, or an empty view when it has none.
std::string_view scene_key_meaning(std::string_view path);

}  // namespace nimbus
