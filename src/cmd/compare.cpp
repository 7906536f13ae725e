// `nimbus compare A.h5 B.h5 [--json] [--image-a A.exr --image-b B.exr]`: the error of run A
// against the reference run B (src/analysis/compare.h): per band, relative L2 and max relative
// error of fields/fluence_diffuse/<band> over cells with density > 0, and the RMS of
// (a - b) / stderr when B has fields/fluence_diffuse_stderr/<band> (a Monte Carlo reference);
// image RMSE and relative error when both images are given. Warns (and flags in --json) when
// the density fields or the cell sizes of A and B differ: runs of different media; and when their
// stored scenes differ in the problem's other settings (problem_differences). RMS z leaves out
// the cells without a usable standard error (compare.h) and says how many it used. A metric whose denominator is
// zero (a zero reference field, a black reference image; src/analysis/compare.h) is printed as
// "undefined" with a line saying why and giving the absolute difference; in --json it is null
// and the band (or image) gains "undefined": the reason. Rank 0 reads and prints; an error is
// reported on every rank.
#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include <toml.hpp>
#include <nlohmann/json.hpp>

#include "io/output/hdf5_reader.h"
#include "io/output/image_io.h"
#include "io/scene/scene_toml.h"
#include "src/analysis/compare.h"
#include "src/cmd/commands.h"
#include "src/core/error.h"
#include "src/core/log.h"

namespace nimbus::cmd {
namespace {

// The scene the run that wrote `file` stored (its /scene attribute), read for its grid and bands
// only: the medium is read as a box, so an imported density need not still be where the run
// found it. Empty when the file has no readable scene (written by another program), with a
// warning: the cell sizes are then not compared.
std::optional<Scene> stored_scene(const std::string& file) {
    try {
        return load_scene_string(read_string_attribute(file, "/scene", "toml"), file, {"medium.kind=\"box\""});
    } catch (const Error& e) {
        log::warn("'{}': its stored scene cannot be read, so its cell size is not compared: {}", file, e.what());
        return std::nullopt;
    }
}

// Where two toml values differ, as dotted key paths under `path` (tables key by key, arrays of
// tables element by element, anything else as a whole).
void toml_differences(const toml::value& a, const toml::value& b, const std::string& path,
                      std::vector<std::string>& out) {
    if (a.is_table() && b.is_table()) {
        std::vector<std::string> keys;
        for (const auto& [k, v] : a.as_table()) keys.push_back(k);
        for (const auto& [k, v] : b.as_table())
            if (!a.contains(k)) keys.push_back(k);
        static const toml::value missing;
        for (const std::string& k : keys)
            toml_differences(a.contains(k) ? a.at(k) : missing, b.contains(k) ? b.at(k) : missing,
                             path + "." + k, out);
    } else if (a.is_array() && b.is_array() && a.size() == b.size() && !a.as_array().empty() &&
               a.as_array()[0].is_table()) {
        for (std::size_t i = 0; i < a.size(); ++i)
            toml_differences(a.as_array()[i], b.as_array()[i], fmt::format("{}[{}]", path, i), out);
    } else if (!(a == b)) {
        out.push_back(path);
    }
}

// The settings of the problem whose fields A and B hold that differ between their scenes: the
// optics, the lights, the volume sources and the periodic faces (the medium is compared by its
// fields), and with images also what they are seen through (camera, background, render mode
// and glow). The model, its options, the light method, the ray caster's step and early
// termination and the outputs may differ: that is what compare is for.
// Both scenes are written back by scene_to_toml, so one setting is one text.
std::vector<std::string> problem_differences(const Scene& a, const Scene& b, bool images) {
    std::istringstream text_a(scene_to_toml(a)), text_b(scene_to_toml(b));
    const toml::value va = toml::parse(text_a, "A"), vb = toml::parse(text_b, "B");
    const bool no_sun = !a.sun.enabled && !b.sun.enabled;
    auto dark = [](const Scene& s) {
        return std::all_of(s.sky.radiance.begin(), s.sky.radiance.end(), [](double L) { return L == 0.0; });
    };
    const bool no_sky = dark(a) && dark(b);
    std::vector<std::string> roots = {"optics", "sources", "grid.periodic"};
    if (!no_sun) roots.push_back("sun");
    if (!no_sky) roots.push_back("sky");
    // The render's mode and glow are what the image shows; its step and early termination are
    // the ray caster's accuracy (like a model's options), its exposure the PNG preview's only.
    if (images) roots.insert(roots.end(), {"camera", "background", "render.mode", "render.emission_color"});
    std::vector<std::string> out;
    static const toml::value missing;
    for (const std::string& root : roots) {
        const toml::value* x = &va;
        const toml::value* y = &vb;
        std::istringstream keys(root);
        for (std::string k; std::getline(keys, k, '.');) {
            x = x->is_table() && x->contains(k) ? &x->at(k) : &missing;
            y = y->is_table() && y->contains(k) ? &y->at(k) : &missing;
        }
        std::vector<std::string> found;
        toml_differences(*x, *y, "", found);
        for (const std::string& f : found) out.push_back(root + f);
    }
    return out;
}

// The bands in the order of the reference run's scene, as the user wrote them; names it does
// not list (or all, without a scene) keep their place at the end.
void sort_in_scene_order(const std::optional<Scene>& scene, std::vector<std::string>& bands) {
    std::vector<std::string> order;
    if (scene)
        for (const BandOptics& b : scene->bands) order.push_back(b.name);
    const auto rank = [&](const std::string& name) {
        return std::find(order.begin(), order.end(), name) - order.begin();
    };
    std::stable_sort(bands.begin(), bands.end(), [&](const std::string& x, const std::string& y) { return rank(x) < rank(y); });
}

// The per-band scalar fields compare can assess (flux_diffuse is a vector field).
const std::vector<std::string> kFields = {"fluence_diffuse", "fluence_reduced", "transmittance_sun"};

struct CompareArgs {
    std::string a, b, image_a, image_b;
    std::string field = "fluence_diffuse";
    bool json = false;
};

// A NaN or Inf anywhere makes every metric meaningless (NaN compares false, so a NaN run looked
// identical to itself and "inf" apart from a finite one): refuse, naming the file and values.
template <class T>
void require_finite(const std::vector<T>& v, const std::string& file, const std::string& what) {
    const auto bad = std::count_if(v.begin(), v.end(), [](T x) { return !std::isfinite(x); });
    if (bad > 0)
        throw Error(fmt::format("'{}': {} has {} non-finite value(s) (NaN or Inf) of {}: the run that wrote it "
                                "failed; nothing to compare",
                                file, what, bad, v.size()));
}

nlohmann::json compare_runs(const CompareArgs& args) {
    std::error_code ec;
    if (std::filesystem::equivalent(args.a, args.b, ec))
        log::warn("A and B are the same file ('{}'): every difference below is 0 by construction", args.a);
    const std::string field = "fields/" + args.field, err = field + "_stderr";
    // transmittance_sun is written only when the scene has a sun: say so rather than "no such group".
    if (args.field == "transmittance_sun")
        for (const std::string& f : {args.a, args.b})
            if (!has_link(f, field))
                throw Error(fmt::format("'{}' has no {}: nimbus writes it only for scenes with a sun "
                                        "(sun.enabled = true)", f, field));
    std::vector<std::string> bands = list_group(args.b, field);  // alphabetical
    if (bands.empty()) throw Error(fmt::format("'{}' has no {} datasets", args.b, field));
    const std::optional<Scene> scene_a = stored_scene(args.a), scene_b = stored_scene(args.b);
    sort_in_scene_order(scene_b, bands);
    const FieldData density = read_field(args.b, "fields/density");
    nlohmann::json out = {{"a", args.a}, {"b", args.b}, {"field", args.field}, {"bands", nlohmann::json::array()}};
    // Comparing runs of different media is almost always a mistake: say so, but go on.
    const FieldData density_a = read_field(args.a, "fields/density");
    if (density_a.shape != density.shape)
        throw Error(fmt::format("fields/density: the grids differ: A '{}' has {}x{}x{} cells, B '{}' has {}x{}x{}",
                                args.a, density_a.shape[0], density_a.shape[1], density_a.shape[2], args.b,
                                density.shape[0], density.shape[1], density.shape[2]));
    const double density_diff = max_rel_difference(density_a.values, density.values);
    out["density_max_rel_diff"] = density_diff;
    // The same densities on cells of another size are another medium (other optical depths).
    const double h_a = scene_a ? scene_a->grid.h() : 0.0, h_b = scene_b ? scene_b->grid.h() : 0.0;
    const bool same_cells = !(h_a > 0 && h_b > 0) || std::abs(h_a - h_b) <= kSameMediumTolerance * h_b;
    if (h_a > 0) out["cell_size_m_a"] = h_a;
    if (h_b > 0) out["cell_size_m_b"] = h_b;
    out["same_cells"] = same_cells;
    out["same_medium"] = density_diff <= kSameMediumTolerance && same_cells;
    const bool images = !args.image_a.empty() || !args.image_b.empty();
    if (scene_a && scene_b) {
        const std::vector<std::string> diff = problem_differences(*scene_a, *scene_b, images);
        out["same_problem"] = diff.empty();
        out["problem_differences"] = diff;
    }
    // Bands of A that the reference lacks are not compared: listed, so that the report says so.
    std::vector<std::string> not_compared;
    for (const std::string& band : list_group(args.a, field))
        if (std::find(bands.begin(), bands.end(), band) == bands.end()) not_compared.push_back(band);
    sort_in_scene_order(scene_a, not_compared);
    out["bands_not_in_b"] = not_compared;
    for (const std::string& band : bands) {
        const std::string path = field + "/" + band;
        if (!has_dataset(args.a, path)) throw Error(fmt::format("'{}' has no {} (the reference has)", args.a, path));
        const FieldData fa = read_field(args.a, path), fb = read_field(args.b, path);
        if (fa.ncomp != 1 || fb.ncomp != 1) throw Error(fmt::format("{}: not a scalar field", path));
        if (fa.shape != fb.shape)
            throw Error(fmt::format("{}: the grids differ: A '{}' has {}x{}x{} cells, B '{}' has {}x{}x{}", path,
                                    args.a, fa.shape[0], fa.shape[1], fa.shape[2], args.b, fb.shape[0], fb.shape[1],
                                    fb.shape[2]));
        require_finite(fa.values, args.a, path);
        require_finite(fb.values, args.b, path);
        // The standard errors of Monte Carlo runs: B's makes RMS z, A's joins it (two runs).
        auto read_stderr = [&](const std::string& file, std::vector<double>& s) {
            if (!has_dataset(file, err + "/" + band)) return false;
            s = read_field(file, err + "/" + band).values;
            require_finite(s, file, err + "/" + band);
            return true;
        };
        std::vector<double> stderr_a, stderr_b;
        const bool with_stderr = read_stderr(args.b, stderr_b);
        const bool a_stderr = with_stderr && read_stderr(args.a, stderr_a);
        const FieldError e = field_error(fa.values, fb.values, density.values, with_stderr ? &stderr_b : nullptr,
                                         a_stderr ? &stderr_a : nullptr);
        // NaN (undefined) is written as null.
        nlohmann::json j = {{"band", band},           {"rel_l2", e.rel_l2}, {"max_rel", e.max_rel},
                            {"sum_ratio", e.sum_ratio}, {"cells", e.cells},   {"abs_l2", e.abs_l2},
                            {"max_abs", e.max_abs}};
        if (with_stderr) j["rms_z"] = e.rms_z, j["z_cells"] = e.z_cells, j["z_with_stderr_a"] = a_stderr;
        if (!e.undefined.empty()) j["undefined"] = e.undefined;
        out["bands"].push_back(j);
    }
    if (images) {
        if (args.image_a.empty() || args.image_b.empty())
            throw Error("compare: give both --image-a and --image-b");
        const Image ia = read_exr(args.image_a), ib = read_exr(args.image_b);
        if (ia.width != ib.width || ia.height != ib.height)
            throw Error(fmt::format("compare: images differ in size ({}x{} against {}x{})", ia.width, ia.height,
                                    ib.width, ib.height));
        require_finite(ia.rgba, args.image_a, "the image");
        require_finite(ib.rgba, args.image_b, "the image");
        const ImageError e = image_error(ia.rgba, ib.rgba);
        out["image"] = {{"rmse", e.rmse}, {"rel_error", e.rel_error}, {"mean_ratio", e.mean_ratio},
                        {"pixels", e.pixels}};
        if (!e.undefined.empty()) out["image"]["undefined"] = e.undefined;
    }
    return out;
}

// A metric as the table shows it: "undefined" for NaN (compare.h).
std::string metric(double v, const char* spec) {
    return std::isnan(v) ? std::string("undefined") : fmt::format(fmt::runtime(spec), v);
}

void print(const std::string& line) { std::fputs(line.c_str(), stdout); }

void print_table(const nlohmann::json& r) {
    print(fmt::format("{} of {} against reference {}\n", r["field"].get<std::string>(),
                      r["a"].get<std::string>(), r["b"].get<std::string>()));
    print(fmt::format("{:<10} {:>12} {:>12} {:>10} {:>10} {:>10}\n", "band", "rel L2", "max rel", "sum A/B",
                      "RMS z", "cells"));
    for (const auto& b : r["bands"])
        print(fmt::format("{:<10} {:>12} {:>12} {:>10} {:>10} {:>10}\n", b["band"].get<std::string>(),
                          metric(b["rel_l2"].get<double>(), "{:.4e}"),
                          metric(b["max_rel"].get<double>(), "{:.4e}"), metric(b["sum_ratio"].get<double>(), "{:.4f}"),
                          b.contains("rms_z") ? metric(b["rms_z"].get<double>(), "{:.3f}") : "-",
                          b["cells"].get<std::size_t>()));
    // RMS z leaves out the cells without a usable standard error: say how many.
    for (const auto& b : r["bands"])
        if (b.contains("z_cells") && b["z_cells"].get<std::size_t>() > 0 &&
            b["z_cells"].get<std::size_t>() < b["cells"].get<std::size_t>())
            print(fmt::format("{}: RMS z over {} of the {} cells; on the others the standard error{} 0 or at "
                              "least half the value (no path or only a few batches reached them: run with more "
                              "photons)\n",
                              b["band"].get<std::string>(), b["z_cells"].get<std::size_t>(),
                              b["cells"].get<std::size_t>(),
                              b["z_with_stderr_a"].get<bool>() ? " of A or B is" : " of the reference is"));
    // Why a metric is undefined, and what can still be said: the absolute difference.
    for (const auto& b : r["bands"])
        if (b.contains("undefined"))
            print(fmt::format("{}: undefined ({}); |a - b| over the {} cells: L2 {:.4e}, max {:.4e}\n",
                              b["band"].get<std::string>(), b["undefined"].get<std::string>(),
                              b["cells"].get<std::size_t>(), b["abs_l2"].get<double>(),
                              b["max_abs"].get<double>()));
    if (r.contains("image")) {
        const auto& im = r["image"];
        const std::string rel = im.contains("undefined")
                                    ? fmt::format("undefined ({})", im["undefined"].get<std::string>())
                                    : metric(im["rel_error"].get<double>(), "{:.4e}");
        print(fmt::format("image: RMSE {:.4e}, relative error {}, brightness A/B {} over {} pixels\n",
                          im["rmse"].get<double>(), rel, metric(im["mean_ratio"].get<double>(), "{:.4f}"),
                          im["pixels"].get<std::size_t>()));
    }
}

}  // namespace

void add_compare_command(CLI::App& app) {
    auto args = std::make_shared<CompareArgs>();
    CLI::App* cmd = app.add_subcommand(
        "compare", "Report the error of run A against reference run B (HDF5 fields, optionally images).");
    cmd->add_option("A", args->a,
                    "the run to assess: the HDF5 file nimbus run wrote (<output.dir>/<output.name>.h5; "
                    "out/nimbus.h5 unless the scene or --out says otherwise)")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("B", args->b, "the reference run's HDF5 file, e.g. a Monte Carlo run's")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->footer(
        "Per band, over the cells with density: rel L2 = ||a - b||_2 / ||b||_2; max rel = max|a - b| / "
        "max|b| (relative to the reference's maximum, not per cell); RMS z = sqrt(mean((a - b)^2 / s^2)) "
        "where B has a standard error s_b (Monte Carlo), s^2 = s_b^2 (+ s_a^2 when A is a Monte Carlo run too), "
        "over the cells where each s is below half the value: about 1 when A agrees with B within the noise. "
        "Warns when the scenes differ in optics, lights, sources or periodic faces (and, with images, in "
        "camera, background or render mode): different problems. "
        "Images: RMSE over pixels and RGB, relative error ||a - b|| / ||b||.");
    cmd->add_flag("--json", args->json, "print JSON instead of a table");
    cmd->add_option("--field", args->field, "per-band field to compare: fluence_diffuse | fluence_reduced | "
                                             "transmittance_sun")
        ->capture_default_str()
        ->check([](const std::string& f) {
            return std::find(kFields.begin(), kFields.end(), f) != kFields.end()
                       ? std::string()
                       : fmt::format("unsupported field '{}'; choose fluence_diffuse | fluence_reduced | "
                                     "transmittance_sun", f);
        });
    cmd->add_option("--image-a", args->image_a, "image of run A (EXR)")->check(CLI::ExistingFile);
    cmd->add_option("--image-b", args->image_b, "image of the reference (EXR)")->check(CLI::ExistingFile);
    cmd->callback([args] {
        int rank = 0;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        nlohmann::json result;
        run_collective(MPI_COMM_WORLD, [&] {
            if (rank == 0) result = compare_runs(*args);
        });
        if (rank != 0) return;
        if (!result["same_cells"].get<bool>())
            log::warn("the cells of {} and {} differ in size ({:.6g} m against {:.6g} m): these are runs of different "
                      "media, and the errors compare different problems",
                      args->a, args->b, result["cell_size_m_a"].get<double>(), result["cell_size_m_b"].get<double>());
        else if (!result["same_medium"].get<bool>())
            log::warn("the density fields of {} and {} differ (max relative difference {:.3g}): these are runs of "
                      "different media, and the errors compare different problems",
                      args->a, args->b, result["density_max_rel_diff"].get<double>());
        if (result.contains("same_problem") && !result["same_problem"].get<bool>()) {
            const auto& diff = result["problem_differences"];
            std::string keys;
            for (std::size_t i = 0; i < diff.size() && i < 6; ++i) keys += (i ? ", " : "") + diff[i].get<std::string>();
            if (diff.size() > 6) keys += fmt::format(" and {} more", diff.size() - 6);
            log::warn("the scenes of {} and {} differ in {}: these runs solve different problems, and the errors "
                      "mix the model's error with that difference",
                      args->a, args->b, keys);
        }
        if (!result["bands_not_in_b"].empty())
            log::warn("{} has band{} {} that the reference {} lacks: not compared", args->a,
                      result["bands_not_in_b"].size() == 1 ? "" : "s", result["bands_not_in_b"].dump(), args->b);
        if (args->json) std::printf("%s\n", result.dump(2).c_str()); else print_table(result);
    });
}

}  // namespace nimbus::cmd
