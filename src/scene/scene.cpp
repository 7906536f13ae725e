#include "src/scene/scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "src/core/error.h"
#include "src/render/ray_box.h"
#include "src/scene/emission.h"

namespace nimbus {
namespace {

void require(bool ok, const std::string& msg) {
    if (!ok) throw Error(msg);
}

// The output stores fields in single precision: a scene number beyond it (or a product of them,
// a cell's optical thickness, the domain's extent) makes solvers overflow before any output.
constexpr double kFloatMax = std::numeric_limits<float>::max();

// field_per_value: the largest field one unit of the value makes (a radiance L over the sky's
// hemisphere is a fluence of 2π L).
void require_bands(const std::vector<double>& v, int nb, const char* key, double field_per_value = 1.0) {
    require(static_cast<int>(v.size()) == nb || v.size() == 1,
            nb == 1 ? fmt::format("{} has {} values but the scene has 1 band: give 1", key, v.size())
                    : fmt::format("{} has {} values but the scene has {} bands: give 1 or {}", key, v.size(), nb, nb));
    for (double x : v) {
        require(std::isfinite(x) && x >= 0.0, fmt::format("{} = {} must be finite and >= 0", key, x));
        require(x * field_per_value <= kFloatMax,
                field_per_value == 1.0
                    ? fmt::format("{} = {} is beyond single precision ({:.3g}), in which the output stores the "
                                  "fields it scales", key, x, kFloatMax)
                    : fmt::format("{} = {} makes fields of {:.3g} x {} = {:.3g}, beyond single precision ({:.3g}), "
                                  "in which the output stores them", key, x, field_per_value, x,
                                  field_per_value * x, kFloatMax));
    }
}

// [[sources]]: boxes, powers, and whether the model supports volume emission.
void validate_sources(const Scene& scene) {
    const auto& sources = scene.sources;
    const GridSpec& grid = scene.grid;
    for (size_t s = 0; s < sources.size(); ++s) {
        const SourceSpec& src = sources[s];
        const std::string key = fmt::format("sources[{}]", s);
        for (int d = 0; d < 3; ++d) {
            const auto a = static_cast<size_t>(d);
            require(std::isfinite(src.lo[a]) && std::isfinite(src.hi[a]) && src.lo[a] < src.hi[a],
                    fmt::format("{}.lo must be < {}.hi along {} (found {} and {})", key, key, "xyz"[d],
                                src.lo[a], src.hi[a]));
        }
        require_bands(src.power, scene.nbands(), (key + ".power").c_str());
        // Cells without extinction are empty space to the Monte Carlo walk and to diffusion
        // (no segment is tallied there, D is unbounded), so emission into a band with
        // sigma_t = 0 would be kept by dom and lpm and lost by those: refused for every model.
        for (int b = 0; b < scene.nbands(); ++b) {
            const auto bb = static_cast<size_t>(b);
            const double p = src.power.size() == 1 ? src.power[0] : src.power[bb];
            require(!(p > 0 && scene.bands[bb].sigma_t == 0),
                    fmt::format("{}.power: band '{}' emits but its sigma_t is 0 (a medium without "
                                "extinction); give the band sigma_t > 0 or the source power 0 in it",
                                key, scene.bands[bb].name));
            // Periodic on every axis, nothing leaves; at albedo 1 nothing is absorbed either:
            // the emitted power piles up without a steady state (Monte Carlo's photons would
            // never end, diffusion's system is singular).
            require(!(p > 0 && grid.periodic[0] && grid.periodic[1] && grid.periodic[2] &&
                      scene.bands[bb].albedo == 1.0),
                    fmt::format("{}.power: band '{}' emits into a domain periodic along x, y and z with albedo 1: "
                                "its light can neither leave nor be absorbed, so there is no steady state; give "
                                "the band albedo < 1, or leave an axis non-periodic",
                                key, scene.bands[bb].name));
        }
        require(!source_cells(src, grid).empty(),
                fmt::format("{}.lo/hi cover no cell centre of the grid (domain [0, {}] x [0, {}] x [0, {}] in {})",
                            key, grid.n[0] * grid.cell_size, grid.n[1] * grid.cell_size,
                            grid.n[2] * grid.cell_size, grid.unit));
    }
    if (!sources.empty())
        require(scene.model.name == "dom" || scene.model.name == "montecarlo" || scene.model.name == "diffusion" ||
                    scene.model.name == "lpm",
                fmt::format("model.name: model {} does not support [[sources]] (volume emission); "
                            "use dom, diffusion, lpm or montecarlo",
                            scene.model.name));
}

// Band names name the HDF5 datasets fields/<field>/<name> (and the XDMF attributes): they must
// be non-empty, unique, free of '/' and control characters, and not "." or "..".
void validate_band_names(const std::vector<BandOptics>& bands) {
    for (size_t b = 0; b < bands.size(); ++b) {
        const std::string& name = bands[b].name;
        const std::string key = fmt::format("optics[{}].name", b);
        require(!name.empty(), key + " must not be empty: a band name names its datasets in the HDF5 output");
        require(std::none_of(name.begin(), name.end(), [](char c) { return (c >= 0 && c < 0x20) || c == 0x7f; }),
                key + " contains a control character: band names name their datasets in the HDF5 output");
        require(name.find_first_of("/:") == std::string::npos && name != "." && name != "..",
                fmt::format("{} = \"{}\" is not a valid band name: no '/' or ':', and not \".\" or \"..\" (it "
                            "names the HDF5 datasets fields/<field>/<name>, which the XDMF file references as "
                            "<file>.h5:/fields/<field>/<name>)",
                            key, name));
        for (size_t c = 0; c < b; ++c)
            require(bands[c].name != name,
                    fmt::format("{} = \"{}\" repeats optics[{}].name: band names must be unique (each names the "
                                "HDF5 datasets fields/<field>/<name>)",
                                key, name, c));
    }
    // ParaView sees fields/<field>/<name> as the XDMF attribute <field>_<name>: fluence_diffuse of
    // band "stderr_X" and fluence_diffuse_stderr of band "X" would both be
    // fluence_diffuse_stderr_X, and ParaView shows one of them only (a QA finding).
    for (size_t b = 0; b < bands.size(); ++b)
        for (size_t c = 0; c < bands.size(); ++c)
            require(bands[b].name != "stderr_" + bands[c].name,
                    fmt::format("optics[{}].name = \"{}\" clashes with optics[{}].name = \"{}\": in ParaView "
                                "(the XDMF file) fluence_diffuse of the one and fluence_diffuse_stderr of the other "
                                "would have the same name; rename one",
                                b, bands[b].name, c, bands[c].name));
}

}  // namespace

namespace {

// A camera point (position or look_at) in metres.
Vec3 camera_world(const CameraSpec& c, const GridSpec& g, const Vec3& v) {
    const double h = g.h();
    return c.domain_units ? Vec3{v.x * g.n[0] * h, v.y * g.n[1] * h, v.z * g.n[2] * h} : v;
}

// The spec's pinhole frame in metres (src/render/camera.h); degenerate when look_at equals the
// position or up is parallel to the view (validate() reports those on their own).
struct PinholeFrame {
    Vec3 position, forward, right, up;
    double half_w = 0, half_h = 0, W = 1, H = 1;
    bool degenerate = true;

    PinholeFrame(const CameraSpec& c, const GridSpec& g) {
        position = camera_world(c, g, c.position);
        const Vec3 view = camera_world(c, g, c.look_at) - position;
        if (!(norm(view) > 0)) return;
        forward = normalized(view);
        const Vec3 side = cross(forward, c.up);
        if (!(norm(side) > 1e-9 * norm(c.up))) return;
        right = normalized(side), up = cross(right, forward);
        half_h = std::tan(0.5 * c.fov_deg * std::numbers::pi / 180.0);
        W = c.width, H = c.height;
        half_w = half_h * W / H;
        degenerate = false;
    }
    // The ray direction through pixel (x, y)'s centre.
    Vec3 pixel_direction(int x, int y) const {
        const double sx = (2.0 * (x + 0.5) / W - 1.0) * half_w, sy = (1.0 - 2.0 * (y + 0.5) / H) * half_h;
        return normalized(forward + right * sx + up * sy);
    }
};

}  // namespace

bool camera_sees_ground(const CameraSpec& c, const GridSpec& g) {
    const PinholeFrame f(c, g);
    if (f.degenerate) return true;
    if (!(f.position.z > 0.0)) return false;
    // The z component of a pixel's direction (before normalizing) is affine in the pixel, so
    // its least is at a corner pixel.
    const int x1 = c.width - 1, y1 = c.height - 1;
    for (const auto& [x, y] : {std::pair{0, 0}, {x1, 0}, {0, y1}, {x1, y1}})
        if (f.pixel_direction(x, y).z < 0.0) return true;
    return false;
}

// The pinhole model of src/render/camera.h, restated on the spec (tests/unit/render/camera_test.cpp
// checks the two agree): whether the ray through some pixel's centre (the ray caster's rays)
// meets the domain in front of the camera. The part of the domain in front of the camera
// projects onto the image plane as the convex hull of its vertices (the box's corners in front
// and its edges' crossings of a near plane), and an image row's centre line crosses that hull in
// one interval: the ends of the pair segments that cross the line. Only the pixel centres in
// that interval (plus a pixel of slack each side against rounding) are traced, a few per row,
// so a domain a few pixels wide in a large image is found (a fixed 33 x 33 fan of rays missed
// one 5 x 4 pixels wide in a 640 x 400 image).
bool camera_sees_domain(const CameraSpec& c, const GridSpec& g) {
    const double h = g.h();
    const Vec3 extent{g.n[0] * h, g.n[1] * h, g.n[2] * h};
    const PinholeFrame f(c, g);
    if (f.degenerate) return true;
    const Vec3 &position = f.position, &forward = f.forward, &right = f.right, &up = f.up;
    const double half_w = f.half_w, half_h = f.half_h, W = f.W, H = f.H;
    auto pixel_sees = [&](int x, int y) {
        double t0, t1;
        return intersect_box(position, f.pixel_direction(x, y), Vec3{0, 0, 0}, extent, t0, t1) && t1 > 0;
    };
    bool inside = true;  // strictly: from a face, a camera looking out sees nothing
    for (int a = 0; a < 3; ++a) inside = inside && position[a] > 0 && position[a] < extent[a];
    if (inside) return true;

    // The domain's vertices in front of the camera, in image coordinates (u, v).
    const double z_near = 1e-9 * (norm(extent) + norm(position));
    std::array<Vec3, 8> corner;  // camera frame: (right, up, forward)
    for (int m = 0; m < 8; ++m) {
        const Vec3 r = Vec3{m & 1 ? extent.x : 0.0, m & 2 ? extent.y : 0.0, m & 4 ? extent.z : 0.0} - position;
        corner[static_cast<size_t>(m)] = Vec3{dot(r, right), dot(r, up), dot(r, forward)};
    }
    std::vector<std::array<double, 2>> uv;
    auto add = [&](const Vec3& q) {
        uv.push_back({0.5 * W * (1.0 + q.x / (q.z * half_w)), 0.5 * H * (1.0 - q.y / (q.z * half_h))});
    };
    for (int m = 0; m < 8; ++m) {
        const Vec3& a = corner[static_cast<size_t>(m)];
        if (a.z >= z_near) add(a);
        for (int bit : {1, 2, 4}) {  // each edge once, from its lower corner
            if (m & bit) continue;
            const Vec3& b = corner[static_cast<size_t>(m | bit)];
            if ((a.z - z_near) * (b.z - z_near) < 0) add(a + (b - a) * ((z_near - a.z) / (b.z - a.z)));
        }
    }
    if (uv.empty()) return false;
    double vmin = uv[0][1], vmax = uv[0][1];
    for (const auto& p : uv) vmin = std::min(vmin, p[1]), vmax = std::max(vmax, p[1]);
    const int y_lo = static_cast<int>(std::clamp(std::ceil(vmin - 0.5) - 1.0, 0.0, H - 1.0));
    const int y_hi = static_cast<int>(std::clamp(std::floor(vmax - 0.5) + 1.0, 0.0, H - 1.0));
    for (int y = y_lo; y <= y_hi; ++y) {
        const double v = std::clamp(y + 0.5, vmin, vmax);
        double ua = std::numeric_limits<double>::infinity(), ub = -ua;
        for (size_t i = 0; i < uv.size(); ++i)
            for (size_t j = i; j < uv.size(); ++j) {
                const auto &p = uv[i], &q = uv[j];
                if ((p[1] - v) * (q[1] - v) > 0) continue;  // the segment p q does not cross the line
                const double u0 = p[1] == q[1] ? p[0] : p[0] + (v - p[1]) / (q[1] - p[1]) * (q[0] - p[0]);
                const double u1 = p[1] == q[1] ? q[0] : u0;  // a segment along the line: both ends
                ua = std::min({ua, u0, u1}), ub = std::max({ub, u0, u1});
            }
        if (!(ua <= ub)) continue;
        const int x_lo = static_cast<int>(std::clamp(std::ceil(ua - 0.5) - 1.0, 0.0, W - 1.0));
        const int x_hi = static_cast<int>(std::clamp(std::floor(ub - 0.5) + 1.0, 0.0, W - 1.0));
        for (int x = x_lo; x <= x_hi; ++x)
            if (pixel_sees(x, y)) return true;
    }
    return false;
}

// The smallest cell edge a scene may have, metres (Scene::validate).
constexpr double kMinCellSize = 1e-9;

void Scene::validate() const {
    for (int d = 0; d < 3; ++d)
        require(grid.n[d] > 0, fmt::format("grid.n{} = {} must be >= 1 (zero-size grid)", "xyz"[d], grid.n[d]));
    // Cell counts are 64-bit, their byte counts too: 2^50 cells is far beyond any machine (the
    // memory check refuses it with advice) and keeps cells x bytes per cell below 2^63.
    const double cells = static_cast<double>(grid.n[0]) * grid.n[1] * grid.n[2];
    require(cells <= 0x1p50, fmt::format("grid.n = [{}, {}, {}] has {:.3g} cells; at most 2^50 = {:.3g} are supported",
                                         grid.n[0], grid.n[1], grid.n[2], cells, 0x1p50));
    require(std::isfinite(grid.unit_scale) && grid.unit_scale > 0,
            fmt::format("grid.unit_scale = {} must be finite and > 0 (metres per unit)", grid.unit_scale));
    require(std::isfinite(grid.cell_size) && grid.cell_size > 0,
            fmt::format("grid.cell_size = {} must be finite and > 0", grid.cell_size));
    // Radiative transfer (geometric optics) needs cells far larger than the wavelength; a
    // nanometre is a bound no medium reaches, and it keeps h², 1/h and the like normal doubles
    // (a unit_scale of 1e-320 gave NaN and "relative change ()" in the solvers).
    require(grid.h() >= kMinCellSize,
            fmt::format("grid.cell_size x grid.unit_scale = {:.3g} m: cells below {:g} m are outside radiative "
                        "transfer (far below the wavelength of light)",
                        grid.h(), kMinCellSize));
    const double extent = std::max({grid.n[0], grid.n[1], grid.n[2]}) * grid.h();
    require(extent <= kFloatMax,
            fmt::format("grid.cell_size = {} puts the domain's side at {:.3g} m, beyond single precision ({:.3g})",
                        grid.cell_size, extent, kFloatMax));
    require(!bands.empty(), "optics: at least one band is required");
    validate_band_names(bands);
    for (size_t b = 0; b < bands.size(); ++b) {
        const auto& o = bands[b];
        require(std::isfinite(o.sigma_t) && o.sigma_t >= 0,
                fmt::format("optics band '{}': sigma_t = {} must be finite and >= 0", o.name, o.sigma_t));
        require(o.sigma_t <= kFloatMax, fmt::format("optics band '{}': sigma_t = {} is beyond single precision ({:.3g})",
                                                    o.name, o.sigma_t, kFloatMax));
        require(o.albedo >= 0 && o.albedo <= 1,
                fmt::format("optics band '{}': albedo = {} is outside [0, 1]", o.name, o.albedo));
        require(std::abs(o.g) < 1, fmt::format("optics band '{}': g = {} must satisfy |g| < 1", o.name, o.g));
    }
    require(std::isfinite(medium.density) && medium.density >= 0,
            fmt::format("medium.density = {} must be finite and >= 0", medium.density));
    // The output stores fields in single precision.
    require(medium.density <= std::numeric_limits<float>::max(),
            fmt::format("medium.density = {} is beyond single precision ({:.3g}), in which the output stores it",
                        medium.density, std::numeric_limits<float>::max()));
    for (const auto& o : bands)
        require(medium.density * o.sigma_t * grid.h() <= kFloatMax,
                fmt::format("medium.density x optics band '{}' sigma_t x the cell size in m = {:.3g}: a cell's optical "
                            "thickness is beyond single precision ({:.3g})",
                            o.name, medium.density * o.sigma_t * grid.h(), kFloatMax));
    if (sun.enabled) {
        const Vec3& w = sun.direction;  // any scale: normalized on load (lights.cpp)
        require(std::isfinite(w.x) && std::isfinite(w.y) && std::isfinite(w.z) && (w.x != 0 || w.y != 0 || w.z != 0),
                "sun.direction must be a non-zero finite vector");
        require_bands(sun.irradiance, nbands(), "sun.irradiance");
    }
    // Also with the sky off: the scene is stored, and a stored -3 failed only once the sky was on.
    require(sky.directions >= 1 && sky.directions <= 4096, "sky.directions must be in [1, 4096]");
    if (!sky.radiance.empty()) require_bands(sky.radiance, nbands(), "sky.radiance", 2.0 * std::numbers::pi);
    // Each below single precision alone, the two together make fluence_reduced (and what it
    // scatters) of E + 2π L: refused here rather than at the write, after the solve (a QA finding).
    if (sun.enabled && !sky.radiance.empty())
        for (int b = 0; b < nbands(); ++b) {
            const auto at = [b](const std::vector<double>& v) { return v.size() == 1 ? v[0] : v[static_cast<size_t>(b)]; };
            const double total = at(sun.irradiance) + 2.0 * std::numbers::pi * at(sky.radiance);
            require(total <= kFloatMax,
                    fmt::format("sun.irradiance + 2π sky.radiance = {:.3g} in band '{}' is beyond single precision "
                                "({:.3g}), in which the output stores the fields they make",
                                total, bands[static_cast<size_t>(b)].name, kFloatMax));
        }
    validate_sources(*this);
    require(camera.width > 0 && camera.height > 0 && camera.width <= 16384 && camera.height <= 16384,
            "camera.resolution must be between 1 and 16384 pixels per side");
    require(camera.fov_deg > 0 && camera.fov_deg < 180, "camera.fov must be in (0, 180) degrees");
    // In metres, as the camera is built (src/render/camera.cpp): with units = "domain" on a domain
    // that is not a cube, an up that is parallel in fractions of the extent is not in metres,
    // and the reverse.
    const Vec3 view = camera_world(camera, grid, camera.look_at) - camera_world(camera, grid, camera.position);
    require(norm(view) > 0, "camera.look_at equals camera.position: the camera looks at nothing");
    require(norm(cross(view, camera.up)) > 1e-9 * norm(view) * norm(camera.up),
            "camera.up is parallel to the view direction camera.look_at - camera.position (in metres)");
    if (output.image) {
        // The image's colours: one band is gray, three are r, g, b (src/render, the Monte Carlo
        // path tracer alike); any other count used to fail only after the whole solve.
        require(nbands() == 1 || nbands() == 3,
                fmt::format("output.image = true: the image maps 1 band (gray) or 3 bands (r, g, b), and the "
                            "scene has {} [[optics]] tables: give 1 or 3, or set output.image = false",
                            nbands()));
        const double h = grid.h();
        // The ground is the plane z = 0 seen from above (the ray caster shades it, Monte Carlo's
        // image leaves it black): a camera under it saw the medium through it.
        const double z = camera_world(camera, grid, camera.position).z;
        require(background.kind != BackgroundSpec::Kind::ground || z > 0.0,
                fmt::format("camera.position is under the ground (z = {:.4g} m; with background.kind = \"ground\" "
                            "the ground is the plane z = 0, seen from above): raise the camera or set "
                            "background.kind = \"color\"",
                            z));
        // With a ground background a view of the ground alone (a shadow beyond the domain) is
        // a picture too.
        const bool ground = background.kind == BackgroundSpec::Kind::ground;
        require(camera_sees_domain(camera, grid) || (ground && camera_sees_ground(camera, grid)),
                fmt::format("camera.look_at: the camera looks at nothing: the domain [0, {:.4g}] x [0, {:.4g}] x "
                            "[0, {:.4g}] m{} is outside its field of view, or so small in it that no pixel's centre "
                            "ray meets it (check camera.position, camera.look_at, camera.fov, camera.resolution and "
                            "units)",
                            grid.n[0] * h, grid.n[1] * h, grid.n[2] * h, ground ? " and the ground" : ""));
    }
    require_bands(background.color, nbands(), "background.color");
    require(background.ground_albedo >= 0 && background.ground_albedo <= 1,
            "background.ground_albedo must be in [0, 1]");
    if (!background.ground_color.empty()) {  // per-band albedo: empty (ground_albedo), 1 or one per band
        require_bands(background.ground_color, nbands(), "background.ground_color");
        for (double a : background.ground_color)
            require(a <= 1.0, fmt::format("background.ground_color = {} is an albedo and must be in [0, 1]", a));
    }
    require(render.step > 0 && render.step <= 4, "render.step must be in (0, 4] cells");
    require(render.early_termination >= 0 && render.early_termination < 1,
            "render.early_termination must be in [0, 1)");
    require_bands(render.emission_color, nbands(), "render.emission_color");
    require(render.exposure > 0 && std::isfinite(render.exposure), "render.exposure must be > 0");
    require(!output.dir.empty(), "output.dir must not be empty: use \".\" for the working folder");
    require(!output.name.empty(), "output.name must not be empty: it names the output files <name>.h5, .xdmf, .exr");
    require(output.name.find_first_of("/:") == std::string::npos,
            fmt::format("output.name = \"{}\" must be a plain file name without '/' or ':' (the XDMF file "
                        "references <name>.h5:/fields/...)",
                        output.name));
}

const char* to_string(RenderMode m) {
    switch (m) {
        case RenderMode::absorption: return "absorption";
        case RenderMode::emission: return "emission";
        case RenderMode::emission_absorption: return "emission_absorption";
        case RenderMode::single_unshadowed: return "single_unshadowed";
        case RenderMode::scattering: return "scattering";
    }
    return "?";
}

const char* to_string(LightSpec::Method m) {
    return m == LightSpec::Method::exact ? "exact" : "sweep";
}

const char* to_string(MediumSpec::Kind k) {
    switch (k) {
        case MediumSpec::Kind::cumulus: return "cumulus";
        case MediumSpec::Kind::box: return "box";
        case MediumSpec::Kind::sphere: return "sphere";
        case MediumSpec::Kind::hdf5: return "hdf5";
        case MediumSpec::Kind::raw: return "raw";
    }
    return "?";
}

}  // namespace nimbus
