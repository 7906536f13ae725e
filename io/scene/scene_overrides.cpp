#include "io/scene/scene_overrides.h"

#include <fmt/format.h>

#include <cctype>
#include <sstream>

#include "io/scene/toml_reader.h"
#include "src/core/error.h"

namespace nimbus::scene_io {
namespace {

struct KeyPart {
    std::string name;
    long index = -1;  // "optics[1]" -> 1; -1 = no index
};

std::string trim(const std::string& s) {
    const auto b = s.find_first_not_of(" \t");
    if (b == std::string::npos) return {};
    const auto e = s.find_last_not_of(" \t");
    return s.substr(b, e - b + 1);
}

bool is_bare_key(const std::string& s) {
    if (s.empty()) return false;
    for (char c : s)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-') return false;
    return true;
}

// "optics[1].albedo" -> {optics,1}, {albedo,-1}; empty on a malformed key.
std::vector<KeyPart> split_key(const std::string& key) {
    std::vector<KeyPart> parts;
    std::stringstream ss(key);
    std::string item;
    while (std::getline(ss, item, '.')) {
        KeyPart p;
        const auto open = item.find('[');
        if (open != std::string::npos) {
            if (item.back() != ']' || open + 2 > item.size() - 1) return {};
            const std::string digits = item.substr(open + 1, item.size() - open - 2);
            for (char c : digits)
                if (!std::isdigit(static_cast<unsigned char>(c))) return {};
            if (digits.size() > 9) return {};
            p.index = std::stol(digits);
            item = item.substr(0, open);
        }
        if (!is_bare_key(item)) return {};
        p.name = item;
        parts.push_back(p);
    }
    if (key.empty() || key.back() == '.') return {};
    return parts;
}

// Parses `text` as a TOML value whose source name is `name`; nullopt if it is not one value.
bool parse_value(const std::string& text, const std::string& name, toml::value& out) {
    try {
        std::istringstream is("value = " + text + "\n");
        const toml::value doc = toml::parse(is, name);
        if (doc.as_table().size() != 1 || !doc.as_table().count("value")) return false;
        out = doc.at("value");
        return true;
    } catch (const std::exception&) {
        return false;
    }
}

}  // namespace

void apply_overrides(toml::value& root, const std::vector<std::string>& overrides,
                     const std::string& source) {
    for (const std::string& o : overrides) {
        const std::string name = kOverridePrefix + o;
        const auto fail = [&](const std::string& what) {
            throw Error(fmt::format("{}: {}: {}", source, name, what));
        };
        const auto eq = o.find('=');
        if (eq == std::string::npos) fail("expected key=value (e.g. grid.n=[32,32,32])");
        const std::string key = trim(o.substr(0, eq)), text = trim(o.substr(eq + 1));
        const std::vector<KeyPart> parts = split_key(key);
        if (parts.empty())
            fail(fmt::format("malformed key '{}': use dotted names with optional [index], e.g. optics[1].albedo", key));

        toml::value value;
        if (!parse_value(text, name, value) && !parse_value(toml_quoted(text), name, value))
            fail("the value cannot be read");

        toml::value* cur = &root;
        std::string path;
        for (size_t p = 0; p < parts.size(); ++p) {
            const KeyPart& part = parts[p];
            const bool last = p + 1 == parts.size();
            if (!cur->is_table()) fail(fmt::format("{} is not a table", path));
            auto& table = cur->as_table();
            path += (path.empty() ? "" : ".") + part.name;
            if (part.index < 0 && last) {
                table[part.name] = value;
                break;
            }
            if (!table.count(part.name)) {
                if (part.index >= 0) fail(fmt::format("{} does not exist, so it has no [{}]", path, part.index));
                toml::value fresh;
                parse_value("{}", name, fresh);
                table[part.name] = fresh;
            }
            cur = &table[part.name];
            if (part.index >= 0) {
                if (!cur->is_array()) fail(fmt::format("{} is not an array", path));
                auto& arr = cur->as_array();
                if (static_cast<size_t>(part.index) >= arr.size())
                    fail(fmt::format("index {} is out of range: {} has {} entr{}", part.index, path,
                                     arr.size(), arr.size() == 1 ? "y" : "ies"));
                path += fmt::format("[{}]", part.index);
                if (last) {
                    // A new array, located at this override (its checks name the --set, not the
                    // file's line): the file's elements and the new one. A check of the whole
                    // array (its length, a per-band count) is then located at the --set too.
                    toml::value changed;
                    parse_value("[]", name, changed);
                    for (size_t q = 0; q < arr.size(); ++q)
                        changed.as_array().push_back(q == static_cast<size_t>(part.index) ? value : arr[q]);
                    *cur = std::move(changed);
                    break;
                }
                cur = &arr[static_cast<size_t>(part.index)];
            }
        }
    }
}

}  // namespace nimbus::scene_io
