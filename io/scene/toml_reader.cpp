#include "io/scene/toml_reader.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include "src/core/error.h"

namespace nimbus::scene_io {
namespace {

const toml::value& empty_table() {
    static const toml::value empty = toml::value(toml::table{});
    return empty;
}

std::string lower(std::string s) {
    for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

std::string short_value(const toml::value& v) {
    if (v.is_string()) return fmt::format("\"{}\"", v.as_string().str);
    if (v.is_integer()) return std::to_string(v.as_integer());
    if (v.is_floating()) return fmt::format("{}", v.as_floating());
    if (v.is_boolean()) return v.as_boolean() ? "true" : "false";
    return "";
}

// "(found string "abc")" for messages about a value of the wrong type.
std::string found(const toml::value& v) {
    if (v.is_array()) {
        const size_t n = v.as_array().size();
        return fmt::format("(found an array of {} {})", n, n == 1 ? "entry" : "entries");
    }
    const std::string s = short_value(v);
    return s.empty() ? fmt::format("(found {})", type_name(v))
                     : fmt::format("(found {} {})", type_name(v), s);
}

}  // namespace

std::string type_name(const toml::value& v) {
    switch (v.type()) {
        case toml::value_t::empty: return "nothing";
        case toml::value_t::boolean: return "boolean";
        case toml::value_t::integer: return "integer";
        case toml::value_t::floating: return "float";
        case toml::value_t::string: return "string";
        case toml::value_t::offset_datetime:
        case toml::value_t::local_datetime:
        case toml::value_t::local_date:
        case toml::value_t::local_time: return "date/time";
        case toml::value_t::array: return "array";
        case toml::value_t::table: return "table";
    }
    return "value";
}

std::string where(const std::string& source, const toml::value& v) {
    const toml::source_location loc = v.location();
    const std::string& file = loc.file_name();
    if (file.rfind(kOverridePrefix, 0) == 0) return fmt::format("{}: {}", source, file);
    if (file == "unknown file") return source;
    return fmt::format("{}:{}", file, loc.line());
}

std::size_t edit_distance(const std::string& a, const std::string& b) {
    const std::size_t n = a.size(), m = b.size();
    std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
    for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
    for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
    for (std::size_t i = 1; i <= n; ++i)
        for (std::size_t j = 1; j <= m; ++j) {
            const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
            d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
                d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
        }
    return d[n][m];
}

std::string closest_name(const std::string& name, const std::vector<std::string>& allowed) {
    std::string best;
    std::size_t best_d = std::numeric_limits<std::size_t>::max();
    for (const auto& a : allowed) {
        const std::string la = lower(a), ln = lower(name);
        const bool prefix = ln.size() >= 3 && (la.rfind(ln, 0) == 0 || ln.rfind(la, 0) == 0);
        const std::size_t dist = la == ln ? 0 : prefix ? 1 : edit_distance(name, a);
        if (dist < best_d) {
            best_d = dist;
            best = a;
        }
    }
    const std::size_t limit = std::min<std::size_t>(2, std::max<std::size_t>(1, name.size() / 2));
    return best_d <= limit ? best : std::string{};
}

std::string join(const std::vector<std::string>& names) {
    std::string s;
    for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
    return s;
}

TableReader::TableReader(const std::string& source, const toml::value& table, std::string path,
                         std::vector<std::string> allowed)
    : source_(source), v_(&table), path_(std::move(path)) {
    if (!table.is_table())
        throw Error(fmt::format("{}: {} must be a table {}", where(source_, table), path_,
                                found(table)));
    // Report the unknown key that comes first in the file, so the message is deterministic.
    const std::string* unknown = nullptr;
    std::uint_least32_t unknown_line = 0;
    for (const auto& [key, value] : table.as_table()) {
        if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
        const auto line = value.location().line();
        if (!unknown || line < unknown_line || (line == unknown_line && key < *unknown)) {
            unknown = &key;
            unknown_line = line;
        }
    }
    if (unknown) {
        const std::string hint = closest_name(*unknown, allowed);
        throw Error(fmt::format("{}: {}: unknown key{}; allowed: {}",
                                where(source_, table.as_table().at(*unknown)), key_path(*unknown),
                                hint.empty() ? "" : fmt::format("; did you mean '{}'?", hint),
                                join(allowed)));
    }
}

bool TableReader::has(const std::string& key) const { return v_->as_table().count(key) != 0; }

const toml::value& TableReader::at(const std::string& key) const { return v_->as_table().at(key); }

std::string TableReader::key_path(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
}

void TableReader::fail(const std::string& key, const std::string& what) const {
    const toml::value& v = has(key) ? at(key) : *v_;
    throw Error(fmt::format("{}: {} {}", where(source_, v), key_path(key), what));
}

double TableReader::number(const toml::value& v, const std::string& key,
                           const std::string& expected) const {
    // TOML has nan and inf literals; no scene number means either, and a NaN would slip
    // through every range check written as `x < lo || x > hi`.
    if (v.is_floating() && !std::isfinite(v.as_floating()))
        fail(key, fmt::format("= {} must be a finite number", v.as_floating()));
    // toml11 reads a literal beyond the double range (1e400) as the largest double, silently:
    // that value itself is therefore refused, as the integer limits are below.
    if (v.is_floating() && std::abs(v.as_floating()) == std::numeric_limits<double>::max())
        fail(key, "is beyond the range of a double (about 1.8e308): must be a finite number");
    if (v.is_floating()) return v.as_floating();
    if (v.is_integer()) return static_cast<double>(v.as_integer());
    fail(key, fmt::format("must be {} {}", expected, found(v)));
}

std::int64_t TableReader::integer(const std::string& key, std::int64_t lo, std::int64_t hi) const {
    const toml::value& v = at(key);
    std::int64_t x = 0;
    // toml11 reads a literal beyond the 64-bit range as the nearest limit, silently: the limits
    // themselves are therefore refused as "out of range" (a seed of 2^64 ran as 2^63 - 1).
    constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max(), kMin = std::numeric_limits<std::int64_t>::min();
    hi = std::min(hi, kMax - 1);
    lo = std::max(lo, kMin + 1);
    if (v.is_integer()) {
        x = v.as_integer();
    } else if (v.is_floating() && std::isfinite(v.as_floating()) && v.as_floating() == std::floor(v.as_floating())) {
        const double f = v.as_floating();  // e.g. photons = 1e6
        if (std::abs(f) >= 9e18)
            fail(key, f > 0 ? fmt::format("= {:g} is too large (at most {})", f, hi)
                            : fmt::format("= {:g} is too small (at least {})", f, lo));
        x = static_cast<std::int64_t>(f);
    } else {
        fail(key, fmt::format("must be an integer {}", found(v)));
    }
    if (x == kMax || x == kMin)  // the caller's bound, not the type's far one
        fail(key, x == kMax ? fmt::format("is beyond the 64-bit integer range (at most {})", hi)
                            : fmt::format("is beyond the 64-bit integer range (at least {})", lo));
    // One bound in the message: the other is the type's far limit, which would only confuse.
    if (x > hi) fail(key, fmt::format("= {} is too large (at most {})", x, hi));
    if (x < lo) fail(key, fmt::format("= {} is too small (at least {})", x, lo));
    return x;
}

void TableReader::read(const std::string& key, double& out) const {
    if (has(key)) out = number(at(key), key, "a number");
}

void TableReader::read(const std::string& key, int& out) const {
    if (has(key))
        out = static_cast<int>(integer(key, std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
}

void TableReader::read(const std::string& key, unsigned& out) const {
    if (has(key)) out = static_cast<unsigned>(integer(key, 0, std::numeric_limits<unsigned>::max()));
}

void TableReader::read(const std::string& key, std::int64_t& out) const {
    if (has(key))
        out = integer(key, std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::max());
}

void TableReader::read(const std::string& key, std::uint64_t& out) const {
    // TOML integers are signed 64-bit: seeds above 2^63 - 1 cannot be written in a file.
    if (has(key))
        out = static_cast<std::uint64_t>(integer(key, 0, std::numeric_limits<std::int64_t>::max()));
}

void TableReader::read(const std::string& key, bool& out) const {
    if (!has(key)) return;
    const toml::value& v = at(key);
    if (!v.is_boolean()) fail(key, fmt::format("must be true or false {}", found(v)));
    out = v.as_boolean();
}

void TableReader::read(const std::string& key, std::string& out) const {
    if (!has(key)) return;
    const toml::value& v = at(key);
    // A number or a date where text belongs is usually text that TOML read as one (--set
    // output.name=2024): say how to quote it.
    if (!v.is_string())
        fail(key, fmt::format("must be a string {}{}", found(v),
                              v.is_array() || v.is_table() ? ""
                                                           : "; quote text that looks like a number or a date: "
                                                             "key = \"2024\" in a file, --set 'key=\"2024\"'"));
    out = v.as_string().str;
}

void TableReader::read(const std::string& key, std::array<int, 3>& out) const {
    if (!has(key)) return;
    const toml::value& v = at(key);
    const auto bad = [&] { fail(key, fmt::format("must be an array of 3 integers {}", found(v))); };
    if (!v.is_array() || v.as_array().size() != 3) bad();
    for (int d = 0; d < 3; ++d) {
        const toml::value& e = v.as_array()[static_cast<size_t>(d)];
        if (!e.is_integer())
            fail(key, fmt::format("must be an array of 3 integers: entry {} is not an integer {}", d, found(e)));
        if (e.as_integer() < std::numeric_limits<int>::min() || e.as_integer() > std::numeric_limits<int>::max())
            fail(key, fmt::format("entry {} = {} is outside the range of a 32-bit integer", d, e.as_integer()));
        out[static_cast<size_t>(d)] = static_cast<int>(e.as_integer());
    }
}

void TableReader::read(const std::string& key, std::array<double, 3>& out) const {
    if (!has(key)) return;
    const toml::value& v = at(key);
    const std::string expected = "an array of 3 numbers";
    if (!v.is_array() || v.as_array().size() != 3)
        fail(key, fmt::format("must be {} {}", expected, found(v)));
    for (size_t d = 0; d < 3; ++d) out[d] = number(v.as_array()[d], key, expected);
}

void TableReader::read(const std::string& key, std::array<bool, 3>& out) const {
    if (!has(key)) return;
    const toml::value& v = at(key);
    const auto bad = [&] { fail(key, fmt::format("must be an array of 3 booleans {}", found(v))); };
    if (!v.is_array() || v.as_array().size() != 3) bad();
    for (size_t d = 0; d < 3; ++d) {
        if (!v.as_array()[d].is_boolean()) bad();
        out[d] = v.as_array()[d].as_boolean();
    }
}

void TableReader::read(const std::string& key, Vec3& out) const {
    std::array<double, 3> a{out.x, out.y, out.z};
    read(key, a);
    out = {a[0], a[1], a[2]};
}

void TableReader::read(const std::string& key, std::vector<std::string>& out,
                       const std::string& items) const {
    if (!has(key)) return;
    const toml::value& v = at(key);
    const std::string what = "must be an array of " + items;
    if (!v.is_array()) fail(key, what);
    std::vector<std::string> values;
    for (const toml::value& e : v.as_array()) {
        if (!e.is_string()) fail(key, what);
        values.push_back(e.as_string().str);
    }
    out = std::move(values);
}

void TableReader::read_per_band(const std::string& key, std::vector<double>& out) const {
    if (!has(key)) return;
    const toml::value& v = at(key);
    const std::string expected = "a number or an array of numbers (one per band)";
    if (v.is_array()) {
        std::vector<double> values;
        for (const auto& e : v.as_array()) values.push_back(number(e, key, expected));
        out = std::move(values);
    } else {
        out = {number(v, key, expected)};
    }
}

int TableReader::read_choice(const std::string& key, const std::vector<std::string>& choices,
                             int current) const {
    if (!has(key)) return current;
    std::string s;
    read(key, s);
    const auto it = std::find(choices.begin(), choices.end(), s);
    if (it != choices.end()) return static_cast<int>(it - choices.begin());
    const std::string hint = closest_name(s, choices);
    fail(key, fmt::format("= \"{}\" is not allowed{}; allowed: {}", s,
                          hint.empty() ? "" : fmt::format("; did you mean '{}'?", hint), join(choices)));
}

TableReader TableReader::table(const std::string& key, std::vector<std::string> allowed) const {
    return TableReader(source_, has(key) ? at(key) : empty_table(), key_path(key), std::move(allowed));
}

std::vector<TableReader> TableReader::tables(const std::string& key,
                                             std::vector<std::string> allowed) const {
    std::vector<TableReader> out;
    if (!has(key)) return out;
    const toml::value& v = at(key);
    if (!v.is_array()) fail(key, fmt::format("must be an array of tables ([[{}]]) {}", key_path(key), found(v)));
    const auto& arr = v.as_array();
    for (size_t i = 0; i < arr.size(); ++i) {
        const std::string path = fmt::format("{}[{}]", key_path(key), i);
        if (!arr[i].is_table())
            throw Error(fmt::format("{}: {} must be a table {}", where(source_, arr[i]), path, found(arr[i])));
        out.emplace_back(source_, arr[i], path, allowed);
    }
    return out;
}

std::string toml_quoted(const std::string& s) {
    std::string out = "\"";
    for (char c : s) {
        const auto u = static_cast<unsigned char>(c);
        if (c == '"' || c == '\\') {
            out += '\\';
            out += c;
        } else if (u < 0x20 || u == 0x7f) {
            out += fmt::format("\\u{:04X}", static_cast<unsigned>(u));
        } else {
            out += c;
        }
    }
    return out + "\"";
}

}  // namespace nimbus::scene_io
