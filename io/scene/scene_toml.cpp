// Scene files (TOML) -> Scene. The schema is the Scene struct (src/scene/scene.h) and the
// model options (src/model/options.h, whose for_each_option lists each [model.<name>] table's
// keys), one key per field; scenes/default.toml shows every table. Steps: parse (toml11) ->
// apply --set overrides to the tree -> convert table by table (unknown keys, types, choices,
// the medium's own ranges) -> Scene::validate() and the options' validate(), whose messages are
// given the file and line of the offending key.
#include "io/scene/scene_toml.h"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <regex>
#include <sstream>
#include <type_traits>
#include <utility>

#include "io/scene/default_scene.h"
#include "io/scene/scene_overrides.h"
#include "io/scene/toml_reader.h"
#include "src/core/error.h"

namespace nimbus {
namespace {

namespace fs = std::filesystem;
using scene_io::TableReader;

const std::vector<std::string> kUnits = {"m", "km", "cm", "mm", "custom"};
const std::vector<double> kUnitScales = {1.0, 1000.0, 0.01, 0.001};
const std::vector<std::string> kMediumKinds = {"cumulus", "box", "sphere", "hdf5", "raw"};
const std::vector<std::string> kCameraUnits = {"domain", "world"};
const std::vector<std::string> kBackgroundKinds = {"color", "ground"};
const std::vector<std::string> kLightMethods = {"sweep", "exact"};
const std::vector<std::string> kRenderModes = {"absorption", "emission", "emission_absorption",
                                               "single_unshadowed", "scattering"};
// Every model the file format knows (solvers/registry.cpp); a run, and `nimbus info`, reject
// the ones this build lacks.
const std::vector<std::string> kModelNames = {"single", "diffusion", "dom", "lpm", "psf", "montecarlo"};

// One line from toml11's multi-line syntax error: "file:line: malformed TOML: what (hint)".
std::string condense_syntax_error(const toml::exception& e, const std::string& source) {
    std::istringstream lines(e.what());
    std::string line, first, hint, code;
    static const std::regex quoted_line(R"(^\s*\d+\s*\|\s?(.*)$)");  // " 2 | [grid"
    while (std::getline(lines, line)) {
        if (first.empty()) first = line;
        const auto caret = line.find("^---");
        if (caret != std::string::npos) hint = line.substr(caret + 4);
        std::smatch m;
        if (code.empty() && std::regex_match(line, m, quoted_line)) code = m[1];
    }
    first = std::regex_replace(first, std::regex(R"(^\[error\]\s*(toml::\w+:\s*)?)"), "");
    hint = std::regex_replace(hint, std::regex(R"(^\s+|\s+$)"), "");
    const auto& loc = e.location();
    const std::string file = loc.file_name() == "unknown file" ? source : loc.file_name();
    // toml11 calls an unclosed table header "an invalid key": say what is missing.
    code = std::regex_replace(code.substr(0, code.find('#')), std::regex(R"(^\s+|\s+$)"), "");
    const bool array_header = code.rfind("[[", 0) == 0;
    if (array_header ? code.find("]]") == std::string::npos
                     : !code.empty() && code[0] == '[' && code.find(']') == std::string::npos) {
        const std::string name = std::regex_replace(code, std::regex(R"(^\[+|\]+$)"), "");
        return fmt::format("{}:{}: malformed TOML: the table header '{}' is not closed (write '{}')", file,
                           loc.line(), code, array_header ? "[[" + name + "]]" : "[" + name + "]");
    }
    return fmt::format("{}:{}: malformed TOML: {}{}", file, loc.line(), first,
                       hint.empty() ? "" : fmt::format(" ({})", hint));
}

// The value at a dotted path with indices ("optics[1].albedo"), or nullptr.
const toml::value* find_path(const toml::value& root, const std::string& path) {
    const toml::value* cur = &root;
    static const std::regex part(R"(([A-Za-z0-9_]+)(?:\[(\d+)\])?)");
    std::stringstream ss(path);
    std::string item;
    while (std::getline(ss, item, '.')) {
        std::smatch m;
        if (!std::regex_match(item, m, part) || !cur->is_table() || !cur->as_table().count(m[1]))
            return nullptr;
        cur = &cur->as_table().at(m[1]);
        if (m[2].matched) {
            const size_t i = std::stoul(m[2]);
            if (!cur->is_array() || i >= cur->as_array().size()) return nullptr;
            cur = &cur->as_array()[i];
        }
    }
    return cur;
}

// The key a validate() message is about: its first dotted name ("medium.density", "grid.nx"
// -> "grid.n"), or for "optics band 'r': albedo = ..." the failing band's entry.
std::string key_of_validation_message(const std::string& msg, const Scene& scene) {
    std::smatch m;
    if (std::regex_search(msg, m, std::regex(R"(optics band '(.*)': (sigma_t|albedo|g) =)"))) {
        const std::string prop = m[2];
        int match = -1;
        for (int b = 0; b < scene.nbands(); ++b) {
            const BandOptics& o = scene.bands[static_cast<size_t>(b)];
            if (o.name != m[1].str()) continue;
            const bool bad = prop == "sigma_t" ? !(std::isfinite(o.sigma_t) && o.sigma_t >= 0 &&
                                                   o.sigma_t <= std::numeric_limits<float>::max())
                           : prop == "albedo"  ? !(o.albedo >= 0 && o.albedo <= 1)
                                               : !(std::abs(o.g) < 1);
            if (match < 0 || bad) match = b;
            if (bad) break;
        }
        return match < 0 ? std::string("optics") : fmt::format("optics[{}].{}", match, prop);
    }
    if (std::regex_search(msg, m, std::regex(R"([a-z_]+(\[\d+\])?(\.[a-z_]+)+)"))) {
        std::string key = m[0];
        if (key == "grid.nx" || key == "grid.ny" || key == "grid.nz") key = "grid.n";
        return key;
    }
    return {};
}

// Rethrows a validate() failure as "<where>: <key>: <message>" using the key's location.
[[noreturn]] void throw_located(const std::string& msg, const Scene& scene,
                                const toml::value& root, const std::string& source) {
    std::string key = key_of_validation_message(msg, scene);
    // A message about two keys ("sources[0].lo must be < sources[0].hi") is located at the one
    // a --set gave, if any: that is what the user just typed.
    static const std::regex dotted(R"([a-z_]+(\[\d+\])?(\.[a-z_]+)+)");
    for (auto it = std::sregex_iterator(msg.begin(), msg.end(), dotted); it != std::sregex_iterator(); ++it) {
        const toml::value* o = find_path(root, it->str());
        if (o && o->location().file_name().rfind(scene_io::kOverridePrefix, 0) == 0) {
            key = it->str();
            break;
        }
    }
    // The value itself, else its nearest ancestor present in the file.
    const toml::value* v = nullptr;
    for (std::string k = key; !k.empty() && !v;) {
        v = find_path(root, k);
        const auto cut = k.find_last_of(".[");
        k = v || cut == std::string::npos ? std::string{} : k.substr(0, cut);
    }
    const std::string at = v ? scene_io::where(source, *v) : source;
    const bool names_key = !key.empty() && msg.rfind(key, 0) == 0;
    throw Error(names_key || key.empty() ? fmt::format("{}: {}", at, msg)
                                         : fmt::format("{}: {}: {}", at, key, msg));
}

// medium.file as an absolute path: relative paths from the file resolve against the scene
// file's folder; relative paths given with --set resolve against the working directory (where
// the user typed them). Absolute paths make scene_to_toml text valid from any folder.
fs::path resolve_file(const std::string& file, const toml::value& v, const fs::path& base_dir) {
    const bool from_override = v.location().file_name().rfind(scene_io::kOverridePrefix, 0) == 0;
    fs::path p(file);
    if (p.is_relative() && !from_override) p = base_dir / p;
    return fs::absolute(p).lexically_normal();
}

void read_grid(const TableReader& t, GridSpec& g) {
    t.read("n", g.n);
    t.read("cell_size", g.cell_size);
    const int unit = t.read_choice("unit", kUnits, 0);
    g.unit = kUnits[static_cast<size_t>(unit)];
    if (g.unit == "custom") {
        if (!t.has("unit_scale")) t.fail("unit", "= \"custom\" needs grid.unit_scale (metres per unit)");
        t.read("unit_scale", g.unit_scale);
    } else {
        if (t.has("unit_scale")) t.fail("unit_scale", "is only allowed with unit = \"custom\"");
        g.unit_scale = kUnitScales[static_cast<size_t>(unit)];
    }
    t.read("process_grid", g.process_grid);
    for (int p : g.process_grid)
        if (p < 0) t.fail("process_grid", "entries must be >= 0 (0 = choose)");
    t.read("periodic", g.periodic);
}

void read_medium(const TableReader& t, MediumSpec& m, const fs::path& base_dir) {
    m.kind = static_cast<MediumSpec::Kind>(t.read_choice("kind", kMediumKinds, static_cast<int>(m.kind)));
    t.read("density", m.density);
    t.read("noise_amplitude", m.noise_amplitude);
    t.read("noise_scale", m.noise_scale);
    t.read("noise_octaves", m.noise_octaves);
    t.read("seed", m.seed);
    t.read("box_lo", m.box_lo);
    t.read("box_hi", m.box_hi);
    t.read("sphere_center", m.sphere_center);
    t.read("sphere_radius", m.sphere_radius);
    t.read("file", m.file);
    t.read("dataset", m.dataset);
    for (const TableReader& e : t.tables("ellipsoid", {"center", "radii", "density"})) {
        Ellipsoid el;
        e.read("center", el.center);
        e.read("radii", el.radii);
        e.read("density", el.density);
        for (double r : el.radii)
            if (!(r > 0 && std::isfinite(r))) e.fail("radii", "must all be > 0 (grid fractions)");
        if (!(el.density >= 0 && std::isfinite(el.density))) e.fail("density", "must be finite and >= 0");
        m.ellipsoids.push_back(el);
    }
    // Ranges Scene::validate() does not cover, checked here where the line is known.
    if (!(m.noise_amplitude >= 0 && std::isfinite(m.noise_amplitude)))
        t.fail("noise_amplitude", fmt::format("= {} must be finite and >= 0", m.noise_amplitude));
    if (!(m.noise_scale > 0 && std::isfinite(m.noise_scale)))
        t.fail("noise_scale", fmt::format("= {} must be > 0 (grid fractions)", m.noise_scale));
    if (m.noise_octaves < 1 || m.noise_octaves > 16)
        t.fail("noise_octaves", fmt::format("= {} must be in [1, 16]", m.noise_octaves));
    for (int d = 0; d < 3; ++d)
        if (!(m.box_lo[static_cast<size_t>(d)] < m.box_hi[static_cast<size_t>(d)]))
            t.fail(t.has("box_hi") ? "box_hi" : "box_lo",
                   fmt::format("box_lo must be < box_hi along {} (grid fractions)", "xyz"[d]));
    if (!(m.sphere_radius > 0 && std::isfinite(m.sphere_radius)))
        t.fail("sphere_radius", fmt::format("= {} must be > 0 (grid fractions)", m.sphere_radius));
    if (m.dataset.empty()) t.fail("dataset", "must not be empty");
    const bool imported = m.kind == MediumSpec::Kind::hdf5 || m.kind == MediumSpec::Kind::raw;
    if (imported) {
        if (m.file.empty())
            t.fail("kind", fmt::format("= \"{}\" needs medium.file (path, relative to the scene file)",
                                       to_string(m.kind)));
        m.file = resolve_file(m.file, t.at("file"), base_dir).string();
        if (fs::is_directory(m.file))
            t.fail("file", fmt::format("= \"{}\" is a directory, not a density file", m.file));
        if (!fs::is_regular_file(m.file))
            t.fail("file", fmt::format("= \"{}\": file not found", m.file));
    } else if (t.has("file")) {
        m.file = resolve_file(m.file, t.at("file"), base_dir).string();
    }
}

void read_optics(const TableReader& root, std::vector<BandOptics>& bands) {
    const auto tables = root.tables("optics", {"name", "sigma_t", "albedo", "g"});
    if (tables.empty())
        throw Error(fmt::format("{}: optics: at least one [[optics]] table (name, sigma_t, albedo, g) is required",
                                root.has("optics") ? scene_io::where(root.source(), root.at("optics"))
                                                   : root.source()));
    bands.clear();
    for (const TableReader& t : tables) {
        BandOptics o;
        t.read("name", o.name);
        t.read("sigma_t", o.sigma_t);
        t.read("albedo", o.albedo);
        t.read("g", o.g);
        bands.push_back(o);
    }
}

void read_sun(const TableReader& t, SunSpec& s) {
    t.read("enabled", s.enabled);
    t.read("direction", s.direction);
    t.read_per_band("irradiance", s.irradiance);
    // Normalize; a vector already of unit length (to round-off) is kept bit for bit, so that
    // writing and reading a scene gives the same numbers.
    // Any finite non-zero vector: normalized_any_scale neither underflows (1e-200) nor overflows.
    const Vec3& w = s.direction;
    const bool finite_nonzero = std::isfinite(w.x) && std::isfinite(w.y) && std::isfinite(w.z) &&
                                (w.x != 0 || w.y != 0 || w.z != 0);
    if (finite_nonzero && std::abs(norm(w) - 1.0) > 1e-12) s.direction = normalized_any_scale(w);
}

// [[sources]]: boxes of volume emission (lo, hi in the grid's unit; power per band, W/m³).
void read_sources(const TableReader& root, std::vector<SourceSpec>& sources) {
    sources.clear();
    for (const TableReader& t : root.tables("sources", {"lo", "hi", "power"})) {
        SourceSpec src;
        if (!t.has("lo") || !t.has("hi")) t.fail(t.has("lo") ? "hi" : "lo", "is required (position in the grid's unit)");
        t.read("lo", src.lo);
        t.read("hi", src.hi);
        t.read_per_band("power", src.power);
        sources.push_back(src);
    }
}

void read_camera(const TableReader& t, CameraSpec& c) {
    t.read("position", c.position);
    t.read("look_at", c.look_at);
    t.read("up", c.up);
    t.read("fov", c.fov_deg);
    if (t.has("resolution")) {
        const toml::value& v = t.at("resolution");
        if (!v.is_array() || v.as_array().size() != 2 || !v.as_array()[0].is_integer() ||
            !v.as_array()[1].is_integer())
            t.fail("resolution", fmt::format("must be an array of 2 integers [width, height] (found {})",
                                             scene_io::type_name(v)));
        const auto w = v.as_array()[0].as_integer(), h = v.as_array()[1].as_integer();
        if (w < 1 || h < 1 || w > 16384 || h > 16384)
            t.fail("resolution", fmt::format("= [{}, {}] must be between 1 and 16384 pixels per side", w, h));
        c.width = static_cast<int>(w);
        c.height = static_cast<int>(h);
    }
    c.domain_units = t.read_choice("units", kCameraUnits, c.domain_units ? 0 : 1) == 0;
}

// [model.<name>]: the keys of the options' for_each_option (src/model/options.h), each read as
// its member's type. The only list option, model.dom.reflective, holds face names, and its
// type error says so (a new list option needs its own words here).
template <class Options>
void read_options(const TableReader& model, const std::string& name, Options& o) {
    const TableReader t = model.table(name, option_keys(o));
    for_each_option(o, [&](const char* key, auto& value) {
        using T = std::remove_reference_t<decltype(value)>;
        if constexpr (std::is_same_v<T, std::vector<std::string>>)
            t.read(key, value, "face names, e.g. [\"z-\"]");
        else
            t.read(key, value);
    });
}

// Names users reach for that the literature uses for our models: a hint, not an alias, so that
// a scene names each model one way.
const std::vector<std::pair<std::string, std::string>> kModelNameHints = {
    {"blur", "psf (the path-integral blur model, Premoze et al. 2004)"},
    {"pathintegral", "psf (the path-integral blur model, Premoze et al. 2004)"},
    {"path_integral", "psf (the path-integral blur model, Premoze et al. 2004)"},
    {"p1", "diffusion (the P1 diffusion approximation)"},
    {"discrete_ordinates", "dom (discrete ordinates)"},
    {"sn", "dom (discrete ordinates)"},
    {"mc", "montecarlo"},
    {"monte_carlo", "montecarlo"},
    {"singlescatter", "single (single scattering)"},
    {"single_scattering", "single (single scattering)"},
};

void read_model(const TableReader& t, ModelSpec& m) {
    if (t.has("name") && t.at("name").is_string()) {
        std::string name = t.at("name").as_string().str;
        for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        for (const auto& [alias, model] : kModelNameHints)
            if (name == alias)
                t.fail("name", fmt::format("= \"{}\" is not allowed; did you mean {}? allowed: {}",
                                           t.at("name").as_string().str, model, scene_io::join(kModelNames)));
    }
    if (t.has("name")) m.name = kModelNames[static_cast<size_t>(t.read_choice("name", kModelNames, 0))];
    read_options(t, "montecarlo", m.montecarlo);
    read_options(t, "diffusion", m.diffusion);
    read_options(t, "dom", m.dom);
    read_options(t, "lpm", m.lpm);
    read_options(t, "psf", m.psf);
}

Scene convert(const toml::value& tree, const std::string& source, const fs::path& base_dir) {
    Scene s;
    s.source = source;
    const TableReader root(source, tree, "",
                           {"title", "grid", "medium", "optics", "sun", "sky", "sources", "light", "camera",
                            "background", "render", "model", "output"});
    root.read("title", s.title);
    read_grid(root.table("grid", {"n", "cell_size", "unit", "unit_scale", "process_grid", "periodic"}),
              s.grid);
    read_medium(root.table("medium", {"kind", "density", "noise_amplitude", "noise_scale",
                                      "noise_octaves", "seed", "box_lo", "box_hi", "sphere_center",
                                      "sphere_radius", "file", "dataset", "ellipsoid"}),
                s.medium, base_dir);
    read_optics(root, s.bands);
    read_sun(root.table("sun", {"enabled", "direction", "irradiance"}), s.sun);
    const TableReader sky = root.table("sky", {"radiance", "directions"});
    sky.read_per_band("radiance", s.sky.radiance);
    sky.read("directions", s.sky.directions);
    read_sources(root, s.sources);
    const TableReader light = root.table("light", {"method"});
    s.light.method = static_cast<LightSpec::Method>(
        light.read_choice("method", kLightMethods, static_cast<int>(s.light.method)));
    read_camera(root.table("camera", {"position", "look_at", "up", "fov", "resolution", "units"}), s.camera);
    const TableReader bg = root.table("background", {"kind", "color", "ground_albedo", "ground_color"});
    s.background.kind = static_cast<BackgroundSpec::Kind>(
        bg.read_choice("kind", kBackgroundKinds, static_cast<int>(s.background.kind)));
    bg.read_per_band("color", s.background.color);
    bg.read("ground_albedo", s.background.ground_albedo);
    bg.read_per_band("ground_color", s.background.ground_color);
    const TableReader r = root.table("render", {"mode", "step", "early_termination", "emission_color", "exposure"});
    s.render.mode = static_cast<RenderMode>(r.read_choice("mode", kRenderModes, static_cast<int>(s.render.mode)));
    r.read("step", s.render.step);
    r.read("early_termination", s.render.early_termination);
    r.read_per_band("emission_color", s.render.emission_color);
    r.read("exposure", s.render.exposure);
    read_model(root.table("model", {"name", "montecarlo", "diffusion", "dom", "lpm", "psf"}), s.model);
    const TableReader out = root.table("output", {"dir", "name", "hdf5", "image"});
    out.read("dir", s.output.dir);
    out.read("name", s.output.name);
    out.read("hdf5", s.output.hdf5);
    out.read("image", s.output.image);

    try {
        s.validate();
        s.model.montecarlo.validate();
        // Settings diffusion would leave unread are an error only when it is the model.
        if (s.model.name == "diffusion") s.model.diffusion.validate();
        else s.model.diffusion.validate_ranges();
        s.model.dom.validate();
        s.model.lpm.validate();
        s.model.psf.validate();
    } catch (const Error& e) {
        throw_located(e.what(), s, tree, source);
    }
    return s;
}

Scene load(std::istream& in, const std::string& source, const fs::path& base_dir,
           const std::vector<std::string>& overrides) {
    toml::value tree;
    try {
        tree = toml::parse(in, source);
    } catch (const toml::exception& e) {
        throw Error(condense_syntax_error(e, source));
    } catch (const std::exception& e) {
        throw Error(fmt::format("{}: cannot read scene: {}", source, e.what()));
    }
    scene_io::apply_overrides(tree, overrides, source);
    return convert(tree, source, base_dir);
}

}  // namespace

Scene load_scene_file(const std::string& path, const std::vector<std::string>& overrides) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec))
        throw Error(fmt::format("{}: scene file not found", path));
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(fmt::format("{}: cannot open scene file", path));
    return load(in, path, fs::path(path).parent_path(), overrides);
}

Scene load_scene_string(const std::string& toml_text, const std::string& source_name,
                        const std::vector<std::string>& overrides) {
    std::istringstream in(toml_text);
    const bool is_path = !source_name.empty() && source_name.front() != '<';
    return load(in, source_name, is_path ? fs::path(source_name).parent_path() : fs::path(), overrides);
}

Scene default_scene(const std::vector<std::string>& overrides) {
    return load_scene_string(kDefaultSceneToml, "<built-in default>", overrides);
}

}  // namespace nimbus
