// Scene: the typed description of one run. Only io/scene_toml parses text into it; every
// struct here has defaults and the whole scene has validate(). Lengths are in metres after
// the length unit is applied (GridSpec::unit_scale), irradiance in W/m², radiance W/(m² sr).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "src/core/vec3.h"
#include "src/model/options.h"

namespace nimbus {

struct GridSpec {
    std::array<int, 3> n{64, 64, 64};    // cells per axis
    double cell_size = 1.0;              // in `unit`
    std::string unit = "m";              // m, km, cm, mm, or "custom" with unit_scale
    double unit_scale = 1.0;             // metres per unit (set from unit)
    std::array<int, 3> process_grid{0, 0, 0};  // ranks per axis, 0 = choose (slabs along z)
    std::array<bool, 3> periodic{false, false, false};  // periodic x, y, z (z: horizontal light only)
    double h() const { return cell_size * unit_scale; }  // cell edge in metres
};

// One ellipsoid of the procedural cumulus (Max 1995 §2): density falls smoothly from
// `density` at the centre to 0 at the surface; positions and radii in grid fractions [0,1].
struct Ellipsoid {
    std::array<double, 3> center{0.5, 0.5, 0.5};
    std::array<double, 3> radii{0.25, 0.25, 0.25};
    double density = 1.0;
};

struct MediumSpec {
    enum class Kind { cumulus, box, sphere, hdf5, raw };
    Kind kind = Kind::cumulus;
    double density = 1.0;  // scale applied to every kind (box/sphere: their constant value)
    // cumulus
    std::vector<Ellipsoid> ellipsoids;     // empty -> a built-in default cumulus
    double noise_amplitude = 0.6;          // relative perturbation of the edge (0 = smooth)
    double noise_scale = 0.12;             // noise feature size, grid fractions
    int noise_octaves = 4;
    unsigned seed = 7;
    // box: [lo, hi] in grid fractions; sphere: centre and radius in grid fractions
    std::array<double, 3> box_lo{0.0, 0.0, 0.0}, box_hi{1.0, 1.0, 1.0};
    std::array<double, 3> sphere_center{0.5, 0.5, 0.5};
    double sphere_radius = 0.4;
    // imported density: file path (relative to the scene file), HDF5 dataset name;
    // raw files are float32 little-endian, x fastest, with exactly nx*ny*nz values
    std::string file;
    std::string dataset = "density";
};

// Optical properties of one colour band: kappa = rho * sigma_t (1/m for rho = 1).
struct BandOptics {
    std::string name = "gray";
    double sigma_t = 1.0;  // extinction cross-section per unit density, 1/m
    double albedo = 0.9;   // single-scattering albedo a in [0, 1]
    double g = 0.85;       // Henyey-Greenstein asymmetry, |g| < 1
};

struct SunSpec {
    bool enabled = true;
    Vec3 direction{0.3, 0.2, -1.0};  // direction the light TRAVELS (into the scene), normalized on load
    std::vector<double> irradiance{1.0};  // E0 per band, W/m² on a plane normal to direction
};

struct SkySpec {
    std::vector<double> radiance;  // uniform sky radiance per band, W/(m² sr); empty = no sky
    int directions = 8;            // number of direction bins over the upper hemisphere
};

// How the light pass computes tau_rho (solvers/light/sun_transmittance.h).
struct LightSpec {
    enum class Method {
        sweep,  // short characteristics on the sweep engine: O(cells), exact for axis-aligned
                // light and homogeneous or layered media, interpolation error otherwise
        exact,  // long characteristics: a ray per cell centre through the piecewise-constant
                // cells, exact, O(cells x n), a layer's rays summed at once; on slabs pipelined
                // down the chain (each rank integrates the pieces in its slab), other process
                // grids replicate the density
    };
    // exact since the forty-second session: its layer integrals cost 1.4-2.4x the sweep on the
    // clouds up to 128^3 (README, "Layer integrals"), which is 4% off on the default cloud.
    Method method = Method::exact;
};

// One [[sources]] table: an axis-aligned box of isotropic volume emission. lo/hi are positions
// in the scene's length unit (GridSpec::unit) measured from the domain's low corner, like
// cell_size; a cell emits when its centre c satisfies lo <= c < hi on every axis (half-open,
// so boxes that share a face never both cover a cell) AND the cell has density > 0 (emission
// belongs to the medium; the empty cells of a covered box emit nothing). power is the emitted
// power per unit volume into all directions (W/m³), per band or one value for every band; the
// radiance source is q = power / 4π (W/m³/sr). Emitted light, collided or not, is part of
// fluence_diffuse (DESIGN §1). Supported by the dom, diffusion, lpm and montecarlo models
// (validate() rejects a scene with sources for any other model, and emission into a band with
// sigma_t = 0).
struct SourceSpec {
    std::array<double, 3> lo{0.0, 0.0, 0.0};
    std::array<double, 3> hi{0.0, 0.0, 0.0};
    std::vector<double> power{1.0};
};

struct CameraSpec {
    Vec3 position{0.5, -1.6, 0.45};   // grid fractions of the domain extent (unit: domain)
    Vec3 look_at{0.5, 0.5, 0.45};
    Vec3 up{0, 0, 1};
    double fov_deg = 40.0;             // vertical field of view
    int width = 640, height = 360;
    bool domain_units = true;          // position/look_at in fractions of the domain extent
};

struct BackgroundSpec {
    enum class Kind { color, ground };
    Kind kind = Kind::color;
    std::vector<double> color{0.0};    // per band radiance behind the volume
    double ground_albedo = 0.3;        // Lambertian ground at the domain's bottom plane
    std::vector<double> ground_color;  // optional per-band albedo (overrides ground_albedo)
};

// Max 1995's ladder of optical models, used when rendering.
enum class RenderMode {
    absorption,           // I = I0 T                              (Max 1995 §2)
    emission,             // I = I0 + ∫ C kappa ds                 (§3)
    emission_absorption,  // particle model I = I0 T + C (1 - T)   (§4)
    single_unshadowed,    // single scatter, sun not attenuated    (§5)
    scattering,           // single scatter with shadows + the model's diffuse field (§6-7)
};

struct RenderSpec {
    RenderMode mode = RenderMode::scattering;
    double step = 0.5;                 // ray-march step, in cells
    double early_termination = 1e-6;   // stop a ray once what lies behind can change its pixel by
                                       // at most this fraction, in every band (march.h)
    std::vector<double> emission_color{1.0};  // C per band for the emission modes
    double exposure = 1.0;             // PNG preview: value * exposure before sRGB encoding
};

struct ModelSpec {
    std::string name = "single";  // single | diffusion | dom | lpm | psf | montecarlo
    MonteCarloOptions montecarlo;  // [model.montecarlo]
    DiffusionOptions diffusion;    // [model.diffusion]
    DomOptions dom;                // [model.dom]
    LpmOptions lpm;                // [model.lpm]
    PsfOptions psf;                // [model.psf]
};

struct OutputSpec {
    std::string dir = "out";
    std::string name = "nimbus";   // files: <dir>/<name>.h5, .xdmf, .exr, .png
    bool hdf5 = true;
    bool image = true;
};

struct Scene {
    std::string source = "<built-in default>";  // file path (for messages)
    std::string title = "nimbus scene";
    GridSpec grid;
    MediumSpec medium;
    std::vector<BandOptics> bands{BandOptics{}};
    SunSpec sun;
    SkySpec sky;
    std::vector<SourceSpec> sources;  // [[sources]]: volume emission boxes
    LightSpec light;
    CameraSpec camera;
    BackgroundSpec background;
    RenderSpec render;
    ModelSpec model;
    OutputSpec output;

    int nbands() const { return static_cast<int>(bands.size()); }
    // Throws nimbus::Error naming the first problem (e.g. "bands[1].albedo = 1.2 is outside
    // [0, 1]"). io/scene_toml adds file and line; this check needs no text.
    void validate() const;
};

// Whether the ray through some pixel's centre (the ray caster's rays, src/render/camera.h)
// meets the domain box [0, n h] in front of the camera: false means the image would show only
// background, almost always a mistake in camera.position/look_at/units. A degenerate view (look_at == position, up
// parallel to it) counts as seeing: validate() reports those on their own. Pure, no MPI.
bool camera_sees_domain(const CameraSpec& camera, const GridSpec& grid);
// Whether the ray through some pixel's centre meets the ground (the plane z = 0 seen from above:
// the camera above it, a ray going down). Degenerate views count as seeing. Pure, no MPI.
bool camera_sees_ground(const CameraSpec& camera, const GridSpec& grid);

const char* to_string(RenderMode m);
const char* to_string(MediumSpec::Kind k);
const char* to_string(LightSpec::Method m);

}  // namespace nimbus
