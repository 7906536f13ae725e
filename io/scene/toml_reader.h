// Typed, located reads from a parsed TOML tree (toml11 v3.7), for the scene loader only.
// Not collective; no MPI. Every failure throws nimbus::Error with ONE line of the form
//   <where>: <key> <what is wrong and what is allowed>
// where <where> is "file:line" for a value from the scene file, and "file: --set k=v" for a
// value that came from an override (overrides are parsed with that source name, see
// scene_overrides.h), so a message always points at what the user typed.
#pragma once

#include <toml.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "src/core/vec3.h"

namespace nimbus::scene_io {

// Source name given to values parsed from a "--set key=value" override.
inline const std::string kOverridePrefix = "--set ";

// "file:line" or "file: --set k=v" for value v of the scene `source`.
std::string where(const std::string& source, const toml::value& v);

// Optimal-string-alignment distance (insert, delete, substitute, swap neighbours).
std::size_t edit_distance(const std::string& a, const std::string& b);
// The allowed name closest to `name` if it is a likely misspelling (distance <= 2 and less
// than half the name's length, equal ignoring case, or one a prefix of the other), else "".
std::string closest_name(const std::string& name, const std::vector<std::string>& allowed);
// "a, b, c"
std::string join(const std::vector<std::string>& names);

// s as a TOML basic string: quoted, with \" \\ and control characters escaped.
std::string toml_quoted(const std::string& s);

// A view of one TOML table at dotted path `path` ("" for the root, "grid", "optics[1]").
// The constructor rejects keys not in `allowed` (naming the closest allowed key).
class TableReader {
public:
    TableReader(const std::string& source, const toml::value& table, std::string path,
                std::vector<std::string> allowed);

    bool has(const std::string& key) const;
    const toml::value& at(const std::string& key) const;
    std::string key_path(const std::string& key) const;
    [[noreturn]] void fail(const std::string& key, const std::string& what) const;

    // Each read leaves `out` untouched when the key is absent; a present key of the wrong
    // type or out of the representable range is an Error. Floats accept integers.
    void read(const std::string& key, double& out) const;
    void read(const std::string& key, int& out) const;
    void read(const std::string& key, unsigned& out) const;
    void read(const std::string& key, std::int64_t& out) const;
    void read(const std::string& key, std::uint64_t& out) const;
    void read(const std::string& key, bool& out) const;
    void read(const std::string& key, std::string& out) const;
    void read(const std::string& key, std::array<int, 3>& out) const;
    void read(const std::string& key, std::array<double, 3>& out) const;
    void read(const std::string& key, std::array<bool, 3>& out) const;
    void read(const std::string& key, Vec3& out) const;
    // An array of strings; `items` says what they are in the error ("must be an array of <items>").
    void read(const std::string& key, std::vector<std::string>& out,
              const std::string& items = "strings") const;
    // A number (one value for every band) or an array of numbers (one per band).
    void read_per_band(const std::string& key, std::vector<double>& out) const;
    // A string that must be one of `choices`; returns its index, or `current` when absent.
    int read_choice(const std::string& key, const std::vector<std::string>& choices,
                    int current) const;

    // Sub-table `key` (must be a table); absent -> an empty table at this table's location.
    TableReader table(const std::string& key, std::vector<std::string> allowed) const;
    // Array of tables `key` ([[key]]); absent -> empty.
    std::vector<TableReader> tables(const std::string& key, std::vector<std::string> allowed) const;

    const std::string& source() const { return source_; }
    const toml::value& value() const { return *v_; }

private:
    std::int64_t integer(const std::string& key, std::int64_t lo, std::int64_t hi) const;
    double number(const toml::value& v, const std::string& key, const std::string& expected) const;

    std::string source_;
    const toml::value* v_;
    std::string path_;
};

// Name of a TOML type for messages ("string", "integer", "table", ...).
std::string type_name(const toml::value& v);

}  // namespace nimbus::scene_io
