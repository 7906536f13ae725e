// Scene -> TOML text with every field written (the effective scene of a run), in the layout of
// scenes/default.toml. load_scene_string() reads it back to an equal Scene: floats are written
// with the shortest text that reads back bit for bit, per-band values of size 1 as a number,
// lengths in the scene's unit (a unit whose scale is not the named one's becomes "custom").
#include <fmt/format.h>

#include <cmath>
#include <sstream>

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

void write_dom(std::ostream& o, const DomOptions& d) {
    o << "[model.dom]\n";
    o << "quadrature = " << str(d.quadrature) << "\n";
    o << "order = " << d.order << "\n";
    o << "polar = " << d.polar << "\n";
    o << "azimuthal = " << d.azimuthal << "\n";
    o << "legendre_order = " << d.legendre_order << "\n";
    o << "delta_m = " << boolean(d.delta_m) << "\n";
    o << "scheme = " << str(d.scheme) << "\n";
    o << "iteration = " << str(d.iteration) << "\n";
    o << "tolerance = " << num(d.tolerance) << "\n";
    o << "max_iterations = " << d.max_iterations << "\n";
    o << "tile_rows = " << d.tile_rows << "\n";
    o << "octant_overlap = " << d.octant_overlap << "\n";
    o << "reflective = " << list(d.reflective, str) << "\n";
    o << "sky = " << str(d.sky) << "\n";
}

void write_lpm(std::ostream& o, const LpmOptions& l) {
    o << "[model.lpm]\n";
    o << "p = " << l.p << "\n";
    o << "refinement = " << l.refinement << "\n";
    o << "k = " << l.k << "\n";
    o << "solution_bins = " << l.solution_bins << "\n";
    o << "iterations = " << l.iterations << "\n";
    o << "epsilon = " << num(l.epsilon) << "\n";
    o << "tail = " << str(l.tail) << "\n";
}

void write_psf(std::ostream& o, const PsfOptions& p) {
    o << "[model.psf]\n";
    o << "levels = " << p.levels << "\n";
    o << "step_growth = " << num(p.step_growth) << "\n";
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

    const MonteCarloOptions& mc = s.model.montecarlo;
    const DiffusionOptions& df = s.model.diffusion;
    o << "\n[model]\n";
    o << "name = " << str(s.model.name) << "\n";
    o << "[model.montecarlo]\n";
    o << "photons = " << mc.photons << "\n";
    o << "time_budget = " << num(mc.time_budget) << "\n";
    o << "target_rel_error = " << num(mc.target_rel_error) << "\n";
    o << "seed = " << mc.seed << "\n";
    o << "batches = " << mc.batches << "\n";
    o << "roulette_weight = " << num(mc.roulette_weight) << "\n";
    o << "max_replicated_memory_gb = " << num(mc.max_replicated_memory_gb) << "\n";
    o << "image = " << boolean(mc.image) << "\n";
    o << "samples_per_pixel = " << mc.samples_per_pixel << "\n";
    o << "[model.diffusion]\n";
    o << "solver = " << str(df.solver) << "\n";
    o << "tolerance = " << num(df.tolerance) << "\n";
    o << "max_iterations = " << df.max_iterations << "\n";
    o << "margin = " << df.margin << "\n";
    o << "max_transport_length = " << num(df.max_transport_length) << "\n";
    o << "clamp_negative = " << boolean(df.clamp_negative) << "\n";
    o << "delta_scaling = " << boolean(df.delta_scaling) << "\n";
    o << "flux_limiter = " << str(df.flux_limiter) << "\n";
    o << "limiter_iterations = " << df.limiter_iterations << "\n";
    o << "limiter_tolerance = " << num(df.limiter_tolerance) << "\n";
    o << "petsc_options = " << str(df.petsc_options) << "\n";
    write_dom(o, s.model.dom);
    write_lpm(o, s.model.lpm);
    write_psf(o, s.model.psf);

    o << "\n[output]\n";
    o << "dir = " << str(s.output.dir) << "\n";
    o << "name = " << str(s.output.name) << "\n";
    o << "hdf5 = " << boolean(s.output.hdf5) << "\n";
    o << "image = " << boolean(s.output.image) << "\n";
    return o.str();
}

}  // namespace nimbus
