#include "src/pipeline/pipeline.h"

#include <H5public.h>
#include <HYPRE_config.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <petscversion.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>
#include <fstream>

#include <unistd.h>

#include "io/output/hdf5_writer.h"
#include "io/output/image_io.h"
#include "io/output/output_files.h"
#include "io/scene/density_import.h"
#include "io/scene/scene_toml.h"
#include "solvers/light/sun_transmittance.h"
#include "solvers/registry.h"
#include "src/core/error.h"
#include "src/core/interrupt_cleanup.h"
#include "src/core/log.h"
#include "src/core/mpi_io_path.h"
#include "src/render/raycaster.h"
#include "src/scene/emission.h"

namespace nimbus {
namespace {

namespace fs = std::filesystem;

// The output folders a run created (rank 0), removed again if the run fails before its outputs
// are committed, so that a failed run leaves no empty folder behind. Only folders that are empty
// then are removed (fs::remove does not remove a folder with files), deepest first.
class CreatedFolders {
public:
    CreatedFolders() { interrupt_cleanup::clear(); }  // this run has written nothing yet
    void add(const fs::path& p) {
        created_.push_back(p);
        interrupt_cleanup::add_folder(p.string());  // a signal does not run the destructor
    }
    // The run is done: its folders stay, and a later signal says that its outputs (if it
    // wrote any) are complete.
    void keep(bool wrote) {
        created_.clear();
        kept_ = true;
        if (wrote)
            interrupt_cleanup::committed();
        else
            interrupt_cleanup::clear();
    }
    ~CreatedFolders() {
        if (kept_) return;
        std::error_code ec;
        for (auto it = created_.rbegin(); it != created_.rend(); ++it) fs::remove(*it, ec);
        interrupt_cleanup::clear();  // cleaned up: the folder is as it was
    }

private:
    std::vector<fs::path> created_;  // outermost first
    bool kept_ = false;
};

// MPI-IO aborts on long file paths (src/core/mpi_io_path.h; a QA finding: exit 134, created
// folders left behind). The longest path a run opens is the XDMF or HDF5 temporary,
// <dir>/<name>.xdmf.<pid>-<8 hex>.tmp: the absolute <dir>/<name> is kept to kMaxOutputStem
// characters, which leaves that temporary (at most 26 more) within kMaxMpiIoPath. Checked before
// any folder is made; every rank decides alike (the same scene and working directory).
constexpr size_t kMaxOutputStem = 200;
static_assert(kMaxOutputStem + 26 <= kMaxMpiIoPath);

void check_output_path_length(MPI_Comm comm, const Scene& scene) {
    std::error_code ec;
    const std::string stem = (fs::absolute(scene.output.dir, ec) / scene.output.name).lexically_normal().string();
    check_collective(comm, stem.size() <= kMaxOutputStem,
                     fmt::format("output path '{}' is {} characters long, more than the {} nimbus allows (Open MPI's "
                                 "MPI-IO aborts on file paths of about 245): use a shorter output.dir (--out) or "
                                 "output.name",
                                 stem, stem.size(), kMaxOutputStem));
}

// Rank 0 creates the output folder and checks it is writable; every rank fails together. The
// folders it had to create are added to `created`.
void prepare_output_dir(MPI_Comm comm, const std::string& dir, CreatedFolders& created) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    std::string msg;
    if (rank == 0) {
        std::error_code ec, ec_probe;
        std::vector<fs::path> missing;  // innermost first
        fs::path p = fs::absolute(dir, ec_probe).lexically_normal();
        if (p.filename().empty()) p = p.parent_path();  // "out/" -> "out"
        // symlink_status: a link whose target is missing (or a loop) is the user's, not missing:
        // following it made it look absent, and a failed run removed the link (a QA finding).
        for (; !p.empty() && p != p.parent_path() && !fs::exists(fs::symlink_status(p, ec_probe));
             p = p.parent_path())
            missing.push_back(p);
        // Registered before they exist: a signal during create_directories still finds them
        // (removing a folder that was not made yet is a no-op).
        for (auto it = missing.rbegin(); it != missing.rend(); ++it) created.add(*it);
        fs::create_directories(dir, ec);
        const fs::path probe = fs::path(dir) / ".nimbus_write_test";
        std::ofstream f(probe);
        if (ec || !f) msg = fmt::format("output folder '{}' cannot be created or is not writable", dir);
        f.close();
        fs::remove(probe, ec);
    }
    check_collective(comm, msg.empty(), msg);
}

// The run's outputs must not replace its input density file (a run with output.dir and
// output.name pointing at medium.file used to overwrite the user's data, and the next run failed
// to read it). Rank 0 decides (an output that does not exist yet is no file); every rank fails
// together.
void check_outputs_spare_input(MPI_Comm comm, const Scene& scene) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    std::string msg;
    if (rank == 0 && !scene.medium.file.empty()) {
        const fs::path stem = fs::path(scene.output.dir) / scene.output.name;
        std::vector<std::string> outputs;
        if (scene.output.hdf5) outputs = {".h5", ".xdmf"};
        if (scene.output.image) outputs.insert(outputs.end(), {".exr", ".png"});
        for (const std::string& ext : outputs) {
            std::error_code ec;
            const fs::path out = stem.string() + ext;
            if (fs::equivalent(out, scene.medium.file, ec) && !ec) {
                msg = fmt::format("output '{}' would overwrite the density file medium.file = \"{}\": choose another "
                                  "output.dir or output.name",
                                  out.string(), scene.medium.file);
                break;
            }
        }
    }
    check_collective(comm, msg.empty(), msg);
}

// An output this run does not write (output.hdf5 or output.image false) that an earlier run left
// under the same name stays: said, so that an image and fields of different runs are not taken
// for one run's. Rank 0 (the output folder exists by now).
void warn_of_outputs_left(MPI_Comm comm, const Scene& scene) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    if (rank != 0) return;
    const fs::path stem = fs::path(scene.output.dir) / scene.output.name;
    std::error_code ec;
    const std::string h5 = stem.string() + ".h5", exr = stem.string() + ".exr";
    if (!scene.output.hdf5 && fs::exists(h5, ec))
        log::warn("output.hdf5 = false: {} (and its .xdmf) from an earlier run stays beside this run's image", h5);
    if (!scene.output.image && fs::exists(exr, ec))
        log::warn("output.image = false: {} (and its .png) from an earlier run stays beside this run's fields", exr);
    // Temporaries of a run that was killed stay until removed: said.
    const OutputFiles::Stale stale = OutputFiles::stale_temporaries(scene.output.dir, scene.output.name);
    if (stale.files > 0)
        log::warn("{} temporary file{} of an earlier, killed run ({}.*.tmp, {:.1f} MB) in {}: the process that wrote "
                  "{} no longer runs on this host; remove {} unless a run on another host shares the folder",
                  stale.files, stale.files == 1 ? "" : "s", scene.output.name, static_cast<double>(stale.bytes) / 1e6,
                  scene.output.dir, stale.files == 1 ? "it" : "them", stale.files == 1 ? "it" : "them");
}

nlohmann::json library_versions() {
    int mpi_major = 0, mpi_minor = 0;
    MPI_Get_version(&mpi_major, &mpi_minor);
    char mpi_lib[MPI_MAX_LIBRARY_VERSION_STRING];
    int len = 0;
    MPI_Get_library_version(mpi_lib, &len);
    std::string lib(mpi_lib, static_cast<size_t>(len));
    if (auto nl = lib.find_first_of(",\n"); nl != std::string::npos) lib = lib.substr(0, nl);
    return {{"nimbus", "0.1.0"},
            {"mpi", lib},
            {"mpi_standard", fmt::format("{}.{}", mpi_major, mpi_minor)},
            {"hdf5", fmt::format("{}.{}.{}", H5_VERS_MAJOR, H5_VERS_MINOR, H5_VERS_RELEASE)},
            {"hypre", HYPRE_RELEASE_VERSION},
            {"petsc", fmt::format("{}.{}.{}", PETSC_VERSION_MAJOR, PETSC_VERSION_MINOR, PETSC_VERSION_SUBMINOR)}};
}

void write_fields(Hdf5Writer& out, const Medium& medium, const LightTransport& light,
                  const DiffuseSolution& diffuse, const Decomposition& d) {
    out.write_field("density", medium.rho, "1", "density rho (kappa = rho * sigma_t)");
    const Box& own = d.local();
    for (int b = 0; b < medium.nbands(); ++b) {
        const std::string band = medium.bands[b].name;
        const double sigma_t = medium.bands[b].sigma_t;
        if (!light.lights.empty() && light.lights[0].name == "sun") {
            Field<double> t(own, 0);
            for_each_cell(own, [&](int i, int j, int k) { t(i, j, k) = light.transmittance(0, sigma_t, i, j, k); });
            out.write_field("transmittance_sun/" + band, t, "1", "T_sun = exp(-∫ kappa ds) toward the sun");
        }
        Field<double> fr(own, 0);
        for_each_cell(own, [&](int i, int j, int k) { fr(i, j, k) = light.fluence_reduced(medium, b, i, j, k); });
        out.write_field("fluence_reduced/" + band, fr, "W/m^2", "∫ I_ri dw = Σ E0 T over light terms");
        out.write_field("fluence_diffuse/" + band, diffuse.fluence[static_cast<size_t>(b)], "W/m^2",
                        "∫ I_d dw = 4π U, the multiply scattered fluence");
        if (!diffuse.flux.empty())
            out.write_field("flux_diffuse/" + band, diffuse.flux[static_cast<size_t>(b)], "W/m^2",
                            "F = ∫ I_d w dw");
        if (!diffuse.fluence_stderr.empty())
            out.write_field("fluence_diffuse_stderr/" + band, diffuse.fluence_stderr[static_cast<size_t>(b)],
                            "W/m^2", "standard error of fluence_diffuse (batch means)");
    }
}

void log_scene(const Scene& s, const Decomposition& d, const ScatteringModel& model) {
    log::info("scene: {} ({})", s.title, s.source);
    log::info("grid: {} x {} x {} cells of {} m on {}", s.grid.n[0], s.grid.n[1], s.grid.n[2],
              s.grid.h(), d.describe());
    log::info("medium: {}, {} band(s), model '{}', render mode '{}'", to_string(s.medium.kind),
              s.nbands(), model.name(), to_string(s.render.mode));
    const auto opts = model.options();
    if (!opts.empty()) log::info("model options: {}", opts.dump());
}

// A scene that runs but shows nothing: no medium, or no light for a render mode that shows
// scattered light (absorption and emission modes need none). Legal, so a warning, not an
// error; said once, by rank 0.
void warn_if_dark(const Scene& scene, const Decomposition& d, const Medium& medium,
                  const std::vector<DirectionalLight>& lights) {
    std::int64_t filled = 0;
    double rho_max = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        filled += medium.rho(i, j, k) > 0;
        rho_max = std::max(rho_max, medium.rho(i, j, k));
    });
    MPI_Allreduce(MPI_IN_PLACE, &filled, 1, MPI_INT64_T, MPI_SUM, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, &rho_max, 1, MPI_DOUBLE, MPI_MAX, d.comm());
    double sigma_max = 0.0;
    for (const BandOptics& o : medium.bands) sigma_max = std::max(sigma_max, o.sigma_t);
    // A medium whose thickest cell is this thin does nothing visible; from a file it is most
    // likely misread (a big-endian float32 0.5 read as little-endian is 8.8e-44).
    const double tau_cell = rho_max * sigma_max * medium.grid.h;
    if (filled > 0 && tau_cell < 1e-12)
        log::warn("the medium is practically transparent: its densest cell is {:.3g} ({:.3g} optical depths){}",
                  rho_max, tau_cell,
                  scene.medium.kind == MediumSpec::Kind::raw
                      ? "; medium.file is read as float32 little-endian, x fastest: is the file big-endian?"
                      : "");
    bool lit = false;
    for (const auto& l : lights)
        for (double e : l.E0) lit = lit || e > 0;
    for (const auto& src : scene.sources)
        for (double p : src.power) lit = lit || p > 0;
    // The ground is a backdrop of the image, not an obstacle in the light pass: a sun below the
    // horizon still lights the medium, from below, through it.
    if (scene.sun.enabled && scene.sun.direction.z > 0 && scene.background.kind == BackgroundSpec::Kind::ground)
        log::warn("sun.direction points upward (z = {:.3g}): the sun is below the horizon, yet it lights the medium "
                  "from below through the ground (background.kind = \"ground\" only draws the ground in the image; "
                  "it does not block light): give the sun a downward direction or set sun.enabled = false",
                  scene.sun.direction.z);
    if (filled == 0)
        log::warn("the medium has no non-empty cells (density 0 everywhere): nothing scatters, fluence_diffuse "
                  "is zero and the image shows the background (check medium.density and medium.kind)");
    else if (!lit && (scene.render.mode == RenderMode::scattering || scene.render.mode == RenderMode::single_unshadowed))
        log::warn("the scene has no light: the sun is off or has zero irradiance, there is no sky and no "
                  "[[sources]] emit, so every fluence is zero (check sun.enabled, sun.irradiance, sky.radiance)");
}

}  // namespace

void check_finite_solution(const DiffuseSolution& diffuse, const Decomposition& d, const std::string& model) {
    std::int64_t bad[2] = {0, 0};  // fluence, flux
    for (const auto& f : diffuse.fluence)
        for_each_cell(d.local(), [&](int i, int j, int k) { bad[0] += !std::isfinite(f(i, j, k)); });
    for (const auto& f : diffuse.flux)
        for_each_cell(d.local(), [&](int i, int j, int k) {
            for (int c = 0; c < f.ncomp(); ++c) bad[1] += !std::isfinite(f(i, j, k, c));
        });
    MPI_Allreduce(MPI_IN_PLACE, bad, 2, MPI_INT64_T, MPI_SUM, d.comm());
    if (bad[0] + bad[1] > 0)
        throw Error(fmt::format("model {} produced non-finite values (NaN or Inf): {} in fluence_diffuse, {} in "
                                "flux_diffuse; nothing was written (run with --log-level debug for the solver's "
                                "steps, and see the README's notes on the model's limits)",
                                model, bad[0], bad[1]));
}

void check_finite_image(const Image& image, MPI_Comm comm) {
    auto finite = [](float v) { return std::isfinite(v); };
    std::int64_t bad = static_cast<std::int64_t>(image.rgba.size()) -
                       std::count_if(image.rgba.begin(), image.rgba.end(), finite) +
                       static_cast<std::int64_t>(image.stderr_rgb.size()) -
                       std::count_if(image.stderr_rgb.begin(), image.stderr_rgb.end(), finite);
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT64_T, MPI_SUM, comm);
    if (bad > 0)
        throw Error(fmt::format("the image has {} non-finite values (NaN or Inf): a radiance beyond float32 "
                                "(3.4e38) or a failed render; nothing was written (check render.emission_color, "
                                "the lights' and the sources' strengths)",
                                bad));
}

namespace {

// The medium kinds a medium.<key> applies to (io/scene/key_docs.cpp); empty: every kind.
std::vector<std::string> medium_key_kinds(const std::string& key) {
    if (key.rfind("noise_", 0) == 0 || key == "seed" || key.rfind("ellipsoid", 0) == 0) return {"cumulus"};
    if (key == "box_lo" || key == "box_hi") return {"box"};
    if (key == "sphere_center" || key == "sphere_radius") return {"sphere"};
    if (key == "file") return {"hdf5", "raw"};
    if (key == "dataset") return {"hdf5"};
    return {};
}

}  // namespace

// The output location's checks that need no folder made, so that `nimbus info` refuses what a
// run would, before any solve (a QA finding: info passed all three): the path's length, a
// file where the output folder goes, a folder (or anything but a file) where an output file
// goes, an output that is the density file. Rank 0 looks; every rank fails together.
void check_output_location(MPI_Comm comm, const Scene& scene) {
    if (!(scene.output.hdf5 || scene.output.image)) return;  // a run without outputs opens no file
    check_output_path_length(comm, scene);
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    std::string msg;
    if (rank == 0) {
        std::error_code ec;
        const fs::path dir = scene.output.dir;
        // The nearest folder that exists on the way to it: the run creates the rest there.
        fs::path existing = dir;
        while (!existing.empty() && !fs::exists(existing, ec)) existing = existing.parent_path();
        if (existing.empty()) existing = ".";
        if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
            msg = fmt::format("output folder '{}' cannot be created or is not writable: it is a file", scene.output.dir);
        } else if (!fs::is_directory(existing, ec)) {
            msg = fmt::format("output folder '{}' cannot be created: '{}' is a file", scene.output.dir,
                              existing.string());
        } else if (::access(existing.c_str(), W_OK | X_OK) != 0) {
            msg = fmt::format("output folder '{}' cannot be created or is not writable: '{}' is not writable",
                              scene.output.dir, existing.string());
        } else {
            std::vector<std::string> outputs;
            if (scene.output.hdf5) outputs = {".h5", ".xdmf"};
            if (scene.output.image) outputs.insert(outputs.end(), {".exr", ".png"});
            for (const std::string& ext : outputs) {
                const fs::path out = (dir / scene.output.name).string() + ext;
                const fs::file_status st = fs::symlink_status(out, ec);
                if (fs::exists(st) && !fs::is_regular_file(st) && !fs::is_symlink(st)) {
                    msg = fmt::format("cannot write output file '{}': it exists and is not a file", out.string());
                    break;
                }
            }
        }
    }
    check_collective(comm, msg.empty(), msg);
    check_outputs_spare_input(comm, scene);
}

// Settings of this run's model (and image) that its other settings leave unread, given a value
// other than the default (a scene that only carries the defaults says nothing): said, since
// they have no effect (a QA finding; another model's table is said by load_run_scene's --set
// check, and diffusion refuses its own: DiffusionOptions::validate).
static void warn_of_unread_settings(const Scene& scene) {
    const ModelSpec defaults;
    if (scene.model.name == "dom") {
        const DomOptions& o = scene.model.dom;
        if (o.quadrature != "product" && (o.polar != defaults.dom.polar || o.azimuthal != defaults.dom.azimuthal))
            log::warn("model.dom.polar and azimuthal are read only with quadrature = \"product\" (this run's is "
                      "'{}'): ignored",
                      o.quadrature);
        if (o.quadrature != "level-symmetric" && o.order != defaults.dom.order)
            log::warn("model.dom.order is read only with quadrature = \"level-symmetric\" (this run's is '{}'): "
                      "ignored",
                      o.quadrature);
    }
    if (scene.model.name == "montecarlo") {
        const MonteCarloOptions& o = scene.model.montecarlo;
        if (!o.image && o.samples_per_pixel != defaults.montecarlo.samples_per_pixel)
            log::warn("model.montecarlo.samples_per_pixel is read only with model.montecarlo.image = true: ignored");
        if (o.image && !scene.output.image)
            log::warn("model.montecarlo.image = true, but output.image = false: no image is made");
    }
    if (!scene.output.image) return;  // the rest is about the image
    const BackgroundSpec background;
    if (scene.background.kind != BackgroundSpec::Kind::ground &&
        (scene.background.ground_albedo != background.ground_albedo || !scene.background.ground_color.empty()))
        log::warn("background.ground_albedo and ground_color are read only with background.kind = \"ground\": "
                  "ignored");
    const RenderSpec render;
    const bool emission = scene.render.mode == RenderMode::emission || scene.render.mode == RenderMode::emission_absorption;
    if (!emission && scene.render.emission_color != render.emission_color)
        log::warn("render.emission_color is read only with render.mode = \"emission\" or \"emission_absorption\": "
                  "ignored");
    if (scene.model.name == "montecarlo" && scene.model.montecarlo.image &&
        (scene.render.step != render.step || scene.render.early_termination != render.early_termination))
        log::warn("render.step and early_termination are the ray caster's: the path-traced image "
                  "(model.montecarlo.image = true) does not read them");
}

Scene load_run_scene(MPI_Comm comm, const RunOptions& opts) {
    Scene scene;
    run_collective(comm, [&] {
        scene = opts.scene_path.empty() ? default_scene(opts.overrides)
                                        : load_scene_file(opts.scene_path, opts.overrides);
        if (!opts.out_dir.empty()) scene.output.dir = opts.out_dir;
    });
    // A --set of another model's option is valid (scene files carry options for several models)
    // but has no effect on this run: say so, since it was typed for this run.
    for (const std::string& o : opts.overrides) {
        const std::string key = o.substr(0, o.find('='));
        if (key.rfind("model.", 0) != 0) continue;
        const std::string rest = key.substr(6), sub = rest.substr(0, rest.find('.'));
        if (sub != rest && sub != scene.model.name)
            log::warn("--set {}: ignored, this run's model is '{}' (model.name)", key, scene.model.name);
    }
    // The same for a medium key that the medium's kind does not read.
    const std::string kind = to_string(scene.medium.kind);
    for (const std::string& o : opts.overrides) {
        const std::string key = o.substr(0, o.find('='));
        if (key.rfind("medium.", 0) != 0) continue;
        const std::string rest = key.substr(7), name = rest.substr(0, rest.find_first_of(".["));
        const std::vector<std::string> kinds = medium_key_kinds(name);
        if (kinds.empty() || std::find(kinds.begin(), kinds.end(), kind) != kinds.end()) continue;
        std::string applies;
        for (const std::string& k : kinds) applies += (applies.empty() ? "" : " | ") + k;
        log::warn("--set {}: ignored, medium.kind is '{}' (it applies to {})", key, kind, applies);
    }
    warn_of_unread_settings(scene);
    return scene;
}

RunResult run_pipeline(MPI_Comm comm, const RunOptions& opts) {
    return run_pipeline(comm, load_run_scene(comm, opts));
}

RunResult run_pipeline(MPI_Comm comm, const Scene& scene) {
    Report report;
    RunResult result;
    const double t_start = wall_time();
    std::unique_ptr<ScatteringModel> model;
    run_collective(comm, [&] {
        model = make_model(scene.model);
        // Scenes built in code get the checks a scene file gets (ranges, camera sees the domain).
        scene.validate();
    });
    CreatedFolders created;  // removed again unless the outputs are committed
    if (scene.output.hdf5 || scene.output.image) {
        check_output_location(comm, scene);
        prepare_output_dir(comm, scene.output.dir, created);
        warn_of_outputs_left(comm, scene);
    }

    const Decomposition d(comm, scene.grid.n, scene.grid.process_grid, scene.grid.periodic);
    log_scene(scene, d, *model);

    Medium medium;
    {
        ScopedTimer t(report, "medium");
        medium = load_medium(scene, d);
    }
    // What the model (and the sources) would refuse after the light pass, refused now.
    check_light_method(d, scene.light.method);
    check_volume_sources(volume_sources(scene), medium.rho, d);
    model->check(scene, d, medium);
    check_lights_leave(d, make_lights(scene));  // after the model's own, more specific refusals
    warn_if_dark(scene, d, medium, make_lights(scene));

    const LightTransport light = compute_light_transport(d, medium, make_lights(scene), report, {}, scene.light.method);
    DiffuseSolution diffuse;
    const SolveContext ctx{scene, d, medium, light, report};
    {
        ScopedTimer t(report, "model");
        model->solve(ctx, diffuse);
    }
    check_finite_solution(diffuse, d, model->name());

    Image image;
    if (scene.output.image) {
        if (model->renders_image()) {
            ScopedTimer t(report, "render");
            image = model->render(ctx);
        } else {
            image = render_image(RenderInputs{scene, medium, light, diffuse}, d, report);
        }
        check_finite_image(image, d.comm());
        std::vector<std::string> names;
        for (const BandOptics& b : medium.bands) names.push_back(b.name);
        if (const std::array<int, 3> band = rgb_band_of_channel(names);
            names.size() == 3 && band != std::array<int, 3>{0, 1, 2}) {
            std::string to;  // the channel of each band, in the scene's order
            for (int b = 0; b < 3; ++b)
                to += std::string(to.empty() ? "" : ", ") + "RGB"[std::find(band.begin(), band.end(), b) - band.begin()];
            log::info("image: the bands {} go to the channels {} by their names", fmt::join(names, ", "), to);
        }
        order_channels_by_band_name(image, names);
    }

    const fs::path stem = fs::path(scene.output.dir) / scene.output.name;
    report.values()["total_seconds_before_output"] = wall_time() - t_start;
    // The run's report (collective): the HDF5 file stores it as it stands once the fields are
    // written (so its peak memory counts their write, the output's largest); the returned (and
    // logged) report is taken again at the end, with the output's times.
    const auto summarize = [&] {
        nlohmann::json summary = report.summarize(d.comm());
        summary["model"] = model->name();
        summary["model_options"] = model->options();
        summary["decomposition"] = d.describe();
        summary["grid"] = {{"n", scene.grid.n}, {"h_m", scene.grid.h()}};
        summary["libraries"] = library_versions();
        return summary;
    };
    // Every output goes to a temporary name; commit() makes them all final together, so a
    // failed run leaves none under its final name (and no temporary).
    OutputFiles files(d.comm());
    if (scene.output.hdf5) {
        ScopedTimer t(report, "output/hdf5");
        Hdf5Writer out(d, medium.grid, stem.string() + ".h5", files);
        write_fields(out, medium, light, diffuse, d);
        out.write_string_attribute("/scene", "toml", scene_to_toml(scene));
        out.write_string_attribute("/run", "report", summarize().dump(2));
        out.close();
        result.hdf5_path = out.path();
    }
    if (scene.output.image) {
        result.exr_path = stem.string() + ".exr";
        result.png_path = stem.string() + ".png";
        const std::string exr = files.add(result.exr_path), png = files.add(result.png_path);
        ScopedTimer t(report, "output/image");
        run_collective(d.comm(), [&] {
            if (d.rank() != 0) return;
            try {
                write_exr(exr, image);
                write_png(png, image, scene.render.exposure);
            } catch (const Error& e) {
                throw Error(files.with_final_names(e.what()));
            }
        });
    }
    {
        ScopedTimer t(report, "output/commit");
        files.commit();
    }
    created.keep(scene.output.hdf5 || scene.output.image);
    nlohmann::json summary = summarize();
    // Rank 0's clock, so that the report is the same on every rank.
    double total = wall_time() - t_start;
    MPI_Bcast(&total, 1, MPI_DOUBLE, 0, d.comm());
    summary["total_seconds"] = total;
    result.report = summary;
    return result;
}

}  // namespace nimbus
