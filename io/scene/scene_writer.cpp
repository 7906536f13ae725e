// Scene -> TOML text with every field written (the effective scene of a run), in the layout of
// scenes/default.toml. load_scene_string() reads it back to an equal Scene: floats are written
// with the shortest text that reads back bit for bit, per-band values of size 1 as a number,
// lengths in the scene's unit (a unit whose scale is not the named one's becomes "custom").
#include <fmt/format.h>

#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "io/scene/scene_toml.h"
#include "io/scene/toml_reader.h"

namespace nimbus {
namespace {

std::string num(double x) {
    if (std::isnan(x)) return "nan";
    if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
    std::string s = fmt::format("{}", x);  // shortest round-trip representation
    if (s.find_first_of(".e") == std::string::npos) s += ".0";
    return s;
}

std::string str(const std::string& s) { return scene_io::toml_quoted(s); }

const char* boolean(bool b) { return b ? "true" : "false"; }

template <class T, class F>
std::string list(const T& values, F&& fmt_one) {
    std::string s = "[";
    bool first = true;
    for (const auto& v : values) {
        s += (first ? "" : ", ") + fmt_one(v);
        first = false;
    }
    return s + "]";
}

std::string nums(const std::array<double, 3>& a) { return list(a, num); }
std::string vec(const Vec3& v) { return nums({v.x, v.y, v.z}); }
std::string per_band(const std::vector<double>& v) { return v.size() == 1 ? num(v[0]) : list(v, num); }

// One model option's value, in the form of the rest of the file.
std::string option_value(int v) { return std::to_string(v); }
std::string option_value(std::int64_t v) { return std::to_string(v); }
std::string option_value(std::uint64_t v) { return std::to_string(v); }
std::string option_value(double v) { return num(v); }
std::string option_value(bool v) { return boolean(v); }
std::string option_value(const std::string& v) { return str(v); }
std::string option_value(const std::vector<std::string>& v) { return list(v, str); }

// [model.<name>]: every key of the options' for_each_option (src/model/options.h), in order.
template <class Options>
void write_options(std::ostream& o, const std::string& name, const Options& opts) {
    o << "[model." << name << "]\n";
    for_each_option(opts, [&](const char* key, const auto& value) {
        o << key << " = " << option_value(value) << "\n";
    });
}

// The unit name to write: a named unit only when its scale is exactly the named one's.
bool named_unit(const GridSpec& g) {
    return (g.unit == "m" && g.unit_scale == 1.0) || (g.unit == "km" && g.unit_scale == 1000.0) ||
           (g.unit == "cm" && g.unit_scale == 0.01) || (g.unit == "mm" && g.unit_scale == 0.001);
}

}  // namespace

std::string scene_to_toml(const Scene& s) {
    std::ostringstream o;
    o << "# nimbus scene: every setting of the run (written by nimbus; source: " << s.source << ")\n";
    o << "title = " << str(s.title) << "\n";

    const GridSpec& g = s.grid;
    o << "\n[grid]\n";
    o << "n = " << list(g.n, [](int v) { return std::to_string(v); }) << "\n";
    o << "cell_size = " << num(g.cell_size) << "\n";
    if (named_unit(g)) {
        o << "unit = " << str(g.unit) << "\n";
    } else {
        o << "unit = \"custom\"\nunit_scale = " << num(g.unit_scale) << "\n";
    }
    o << "process_grid = " << list(g.process_grid, [](int v) { return std::to_string(v); }) << "\n";
    o << "periodic = " << list(g.periodic, [](bool v) { return std::string(boolean(v)); }) << "\n";

    const MediumSpec& m = s.medium;
    o << "\n[medium]\n";
    o << "kind = " << str(to_string(m.kind)) << "\n";
    o << "density = " << num(m.density) << "\n";
    o << "noise_amplitude = " << num(m.noise_amplitude) << "\n";
    o << "noise_scale = " << num(m.noise_scale) << "\n";
    o << "noise_octaves = " << m.noise_octaves << "\n";
    o << "seed = " << m.seed << "\n";
    o << "box_lo = " << nums(m.box_lo) << "\n";
    o << "box_hi = " << nums(m.box_hi) << "\n";
    o << "sphere_center = " << nums(m.sphere_center) << "\n";
    o << "sphere_radius = " << num(m.sphere_radius) << "\n";
    if (!m.file.empty()) o << "file = " << str(m.file) << "\n";
    o << "dataset = " << str(m.dataset) << "\n";
    for (const Ellipsoid& e : m.ellipsoids) {
        o << "[[medium.ellipsoid]]\n";
        o << "center = " << nums(e.center) << "\n";
        o << "radii = " << nums(e.radii) << "\n";
        o << "density = " << num(e.density) << "\n";
    }

    for (const BandOptics& b : s.bands) {
        o << "\n[[optics]]\n";
        o << "name = " << str(b.name) << "\n";
        o << "sigma_t = " << num(b.sigma_t) << "\n";
        o << "albedo = " << num(b.albedo) << "\n";
        o << "g = " << num(b.g) << "\n";
    }

    o << "\n[sun]\n";
    o << "enabled = " << boolean(s.sun.enabled) << "\n";
    o << "direction = " << vec(s.sun.direction) << "\n";
    o << "irradiance = " << per_band(s.sun.irradiance) << "\n";

    o << "\n[sky]\n";
    o << "radiance = " << per_band(s.sky.radiance) << "\n";
    o << "directions = " << s.sky.directions << "\n";

    for (const SourceSpec& src : s.sources) {
        o << "\n[[sources]]\n";
        o << "lo = " << nums(src.lo) << "\n";
        o << "hi = " << nums(src.hi) << "\n";
        o << "power = " << per_band(src.power) << "\n";
    }

    o << "\n[light]\n";
    o << "method = " << str(to_string(s.light.method)) << "\n";

    const CameraSpec& c = s.camera;
    o << "\n[camera]\n";
    o << "position = " << vec(c.position) << "\n";
    o << "look_at = " << vec(c.look_at) << "\n";
    o << "up = " << vec(c.up) << "\n";
    o << "fov = " << num(c.fov_deg) << "\n";
    o << "resolution = [" << c.width << ", " << c.height << "]\n";
    o << "units = " << str(c.domain_units ? "domain" : "world") << "\n";

    const BackgroundSpec& bg = s.background;
    o << "\n[background]\n";
    o << "kind = " << str(bg.kind == BackgroundSpec::Kind::ground ? "ground" : "color") << "\n";
    o << "color = " << per_band(bg.color) << "\n";
    o << "ground_albedo = " << num(bg.ground_albedo) << "\n";
    o << "ground_color = " << per_band(bg.ground_color) << "\n";

    const RenderSpec& r = s.render;
    o << "\n[render]\n";
    o << "mode = " << str(to_string(r.mode)) << "\n";
    o << "step = " << num(r.step) << "\n";
    o << "early_termination = " << num(r.early_termination) << "\n";
    o << "emission_color = " << per_band(r.emission_color) << "\n";
    o << "exposure = " << num(r.exposure) << "\n";

    o << "\n[model]\n";
    o << "name = " << str(s.model.name) << "\n";
    write_options(o, "montecarlo", s.model.montecarlo);
    write_options(o, "diffusion", s.model.diffusion);
    write_options(o, "dom", s.model.dom);
    write_options(o, "lpm", s.model.lpm);
    write_options(o, "psf", s.model.psf);

    o << "\n[output]\n";
    o << "dir = " << str(s.output.dir) << "\n";
    o << "name = " << str(s.output.name) << "\n";
    o << "hdf5 = " << boolean(s.output.hdf5) << "\n";
    o << "image = " << boolean(s.output.image) << "\n";
    return o.str();
}

}  // namespace nimbus
