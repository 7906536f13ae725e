// The ray caster's view-path source hook (src/render/view_source.h) and the psf model's image.
//  * A constant source H on any density: the step integration telescopes, so every pixel is
//    exactly H a (1 - T) = H a alpha (sky 0, no lights), whatever the medium and the ranks.
//  * A source depending on the view depth and position, with sample spacing growing along the
//    ray: the image on the world communicator (pieces marched by 2 ranks, depths from the
//    prepass, held values carried by the compositor) equals the one on MPI_COMM_SELF to 1e-5.
//  * The psf model on a procedural cumulus (sun + sky): world equals self to 1e-5; its image is
//    brighter than single scattering alone; held samples converge to sampling every step in
//    the mean: step_growth 0.25 within 5% of it (measured 4%), closer than the default 1 (20%
//    low on this small cloud; measured multiple scattering adds 35.2%, 42.3%, 44.1% of single).
#include <gtest/gtest.h>
#include <mpi.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "io/scene/density_import.h"
#include "solvers/light/sun_transmittance.h"
#include "solvers/psf/psf.h"
#include "solvers/psf/psf_source.h"
#include "src/core/halo.h"
#include "src/physics/lights.h"
#include "src/render/raycaster.h"
#include "src/scene/medium.h"

namespace nimbus {
namespace {

struct World {
    std::unique_ptr<Decomposition> d;
    Medium medium;
    LightTransport light;
    DiffuseSolution none;
};

Scene base_scene() {
    Scene s;
    s.grid.n = {24, 24, 32};
    s.grid.cell_size = 0.25;
    s.bands = {BandOptics{"gray", 1.2, 0.9, 0.85}};
    s.sun.enabled = false;
    s.sky.radiance.clear();
    s.render.mode = RenderMode::scattering;
    s.background.color = {0.0};
    s.camera.position = {1.4, -0.8, 0.9};
    s.camera.look_at = {0.5, 0.5, 0.45};
    s.camera.fov_deg = 55;
    s.camera.width = 40;
    s.camera.height = 30;
    return s;
}

Scene cloud_scene();  // a procedural cumulus under sun and sky (below)

World make_world(MPI_Comm comm, const Scene& s) {
    World w;
    w.d = std::make_unique<Decomposition>(comm, s.grid.n);
    w.medium = load_medium(s, *w.d);
    return w;
}

class ConstantSource final : public ViewRaySource {
public:
    explicit ConstantSource(double H) : H_(H) {}
    void prepare(const Box&, const Decomposition&) override {}
    double spacing(const Vec3&, double, double s_view) const override { return 0.3 + 2.0 * s_view; }
    void sample(const Vec3&, const Vec3&, double, double, double* H) const override { H[0] = H_; }

private:
    double H_;
};

class DepthSource final : public ViewRaySource {
public:
    void prepare(const Box&, const Decomposition&) override {}
    double spacing(const Vec3& x, double tau_view, double s_view) const override {
        return 0.1 + 0.5 * s_view + 0.2 * tau_view + 0.3 * x.z;
    }
    double spacing_bound(double tau_view, double s_view) const override { return 0.1 + 0.5 * s_view + 0.2 * tau_view; }
    void sample(const Vec3& x, const Vec3&, double tau_view, double s_view, double* H) const override {
        H[0] = 1.0 + 0.4 * tau_view + 0.3 * s_view + 0.5 * std::sin(3.0 * x.z);
    }
};

// H = 1 on the medium, 10^7 in a hidden core (the cube test of tests/unit/render's early
// termination, as a view-path source): bounded by 10^7.
class HiddenCoreSource final : public ViewRaySource {
public:
    void prepare(const Box&, const Decomposition&) override {}
    double spacing(const Vec3&, double, double) const override { return 0.0; }  // every step
    void sample(const Vec3& x, const Vec3&, double, double, double* H) const override {
        const bool core = x.x > 2.4 && x.x < 3.6 && x.y > 2.4 && x.y < 3.6 && x.z > 3.4 && x.z < 4.6;
        H[0] = core ? 1e7 : 1.0;
    }
    void radiance_bound(int, double* H) const override { H[0] = 1e7; }
};

Image render_with(const Scene& s, World& w, ViewRaySource* src, Report* out_report = nullptr) {
    Report report;
    RenderInputs in{s, w.medium, w.light, w.none};
    in.view_source = src;
    Image image = render_image(in, *w.d, report);
    if (out_report) *out_report = report;
    return image;
}

double max_rel_diff(const Image& a, const Image& b, double& peak) {
    peak = 0.0;
    for (float v : b.rgba) peak = std::max(peak, static_cast<double>(std::abs(v)));
    double worst = 0.0;
    for (size_t i = 0; i < a.rgba.size(); ++i) worst = std::max(worst, std::abs(static_cast<double>(a.rgba[i]) - b.rgba[i]));
    return worst / peak;
}

int rank() {
    int r = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &r);
    return r;
}

TEST(PsfRenderHook, ConstantSourceTelescopesToHTimesAlbedoTimesOpacity) {
    const Scene s = base_scene();
    World w = make_world(MPI_COMM_WORLD, s);
    ConstantSource src(2.5);
    const Image img = render_with(s, w, &src);
    if (rank() != 0) return;
    int lit = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const float* p = img.pixel(x, y);
            EXPECT_NEAR(p[0], 2.5 * 0.9 * p[3], 2e-6 + 2e-6 * p[0]) << x << " " << y;
            lit += p[3] > 0.01;
        }
    EXPECT_GT(lit, img.width * img.height / 10);
}

TEST(PsfRenderHook, DepthSourceImageIndependentOfRanks) {
    Scene s = base_scene();
    s.render.early_termination = 0.0;
    World ww = make_world(MPI_COMM_WORLD, s), ws = make_world(MPI_COMM_SELF, s);
    DepthSource src;
    const Image a = render_with(s, ww, &src);
    const Image b = render_with(s, ws, &src);
    if (rank() != 0) return;
    double peak = 0.0;
    const double diff = max_rel_diff(a, b, peak);
    std::printf("  depth source: max |world - self| / peak = %.3g (peak %.4g)\n", diff, peak);
    EXPECT_GT(peak, 0.5);
    EXPECT_LE(diff, 1e-5);
}

// Early termination with a view-path source keeps march.h's per-pixel bound: a dense box
// (1.2 optical depths per cell) whose core's source is 10^7 times the rest, 11.5-17 optical
// depths behind its faces (the old rule, T < eps alone, moved pixels over the core by 9%, 1 and
// 2 ranks alike). Against early_termination = 0 every pixel moves by at most eps (+ the
// float32 floor), on the world communicator (2 and 3 ranks: pieces, carried H) and alone.
// B = (2 + 1) S with S = a H_max = 0.9e7 (march_source.h).
TEST(PsfRenderHook, EarlyTerminationBoundsEachPixelWithAViewPathSource) {
    Scene s = base_scene();
    s.medium.kind = MediumSpec::Kind::box;
    s.medium.box_lo = {0.0, 0.0, 0.0};
    s.medium.box_hi = {1.0, 1.0, 1.0};
    s.bands = {BandOptics{"gray", 4.8, 0.9, 0.0}};  // 1.2 optical depths per 0.25 m cell
    s.camera.position = {0.5, -1.0, 0.5};  // domain fractions: the core is 9.6 cells (11.5 optical
    s.camera.look_at = {0.5, 0.5, 0.5};     // depths) behind the front face
    s.camera.fov_deg = 30;
    constexpr double eps = 1e-6, kFloat32Floor = 3e-7;
    HiddenCoreSource src;
    auto render = [&](MPI_Comm comm, double e, Report* r) {
        Scene sc = s;
        sc.render.early_termination = e;
        World w = make_world(comm, sc);
        return render_with(sc, w, &src, r);
    };
    Report cut_report, exact_report;
    const Image exact = render(MPI_COMM_SELF, 0.0, &exact_report);
    const Image world = render(MPI_COMM_WORLD, eps, &cut_report);
    const Image self = render(MPI_COMM_SELF, eps, nullptr);
    if (rank() != 0) return;
    double worst_world = 0.0, worst_self = 0.0;
    int lit = 0;
    for (int y = 0; y < exact.height; ++y)
        for (int x = 0; x < exact.width; ++x) {
            const double want = exact.pixel(x, y)[0];
            if (!(want > 0)) continue;
            lit += want > 10.0;  // the core shows through (elsewhere H a alpha <= 0.9)
            worst_world = std::max(worst_world, std::abs(world.pixel(x, y)[0] - want) / want);
            worst_self = std::max(worst_self, std::abs(self.pixel(x, y)[0] - want) / want);
        }
    const long cut = cut_report.values()["render"]["samples"].get<long>();
    const long all = exact_report.values()["render"]["samples"].get<long>();
    std::printf("  view-path source, early termination: max relative change %.3g (world), %.3g (self); "
                "%d pixels see the core; samples %ld of %ld\n",
                worst_world, worst_self, lit, cut, all);
    EXPECT_GT(lit, 20);
    EXPECT_LE(worst_world, eps + kFloat32Floor);
    EXPECT_LE(worst_self, eps + kFloat32Floor);
    EXPECT_LT(cut, all);  // the cut still saves steps
    EXPECT_NEAR(cut_report.values()["render"]["termination_bound"][0].get<double>(), 3 * 0.9e7, 1e-3);
}

// sample() never exceeds radiance_bound() (the psf model's source on the cloud, sun + sky):
// at every cell centre of the rank and 26 view directions plus the sun's, for view depths 0 .. 40.
// And the bound is tight: it is Σ E0 times the table's largest weight, P_MS at θ = 0 and small l,
// which a lit surface cell seen along the sun reaches up to its T and the sky's share of Σ E0,
// so the worst ratio must be O(1) (a bound twice too large, which would halve the early
// termination it sets, fails).
TEST(PsfModel, SamplesStayWithinTheRadianceBound) {
    Scene s = cloud_scene();
    World w = make_world(MPI_COMM_WORLD, s);
    Report report;
    w.light = compute_light_transport(*w.d, w.medium, make_lights(s), report, {}, s.light.method);
    const SolveContext ctx{s, *w.d, w.medium, w.light, report};
    psf::PsfSource src(ctx, PsfOptions{});
    src.prepare(w.d->local(), *w.d);
    double bound[3];
    src.radiance_bound(3, bound);
    std::vector<Vec3> views{s.sun.direction};
    for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dz = -1; dz <= 1; ++dz)
                if (dx != 0 || dy != 0 || dz != 0) views.push_back(normalized(Vec3{double(dx), double(dy), double(dz)}));
    double worst = 0.0;  // largest H_b / bound_b
    for_each_cell(w.d->local(), [&](int i, int j, int k) {
        if (!(w.medium.rho(i, j, k) > 0)) return;
        const Vec3 x = w.medium.grid.center(i, j, k);
        for (const Vec3& w_out : views)
            for (double tau : {0.0, 0.3, 4.0, 40.0}) {
                double H[3];
                src.sample(x, w_out, tau, 0.25 * tau, H);
                for (int b = 0; b < 3; ++b) worst = std::max(worst, H[b] / bound[b]);
            }
    });
    MPI_Allreduce(MPI_IN_PLACE, &worst, 1, MPI_DOUBLE, MPI_MAX, w.d->comm());
    if (rank() == 0) std::printf("  psf source: max H / bound = %.3g\n", worst);
    EXPECT_LE(worst, 1.0);
    EXPECT_GT(worst, 0.5);
}

Scene cloud_scene() {
    Scene s = base_scene();
    s.bands = {BandOptics{"r", 1.0, 0.99, 0.85}, BandOptics{"g", 1.0, 0.99, 0.85}, BandOptics{"b", 1.1, 0.98, 0.8}};
    s.medium.density = 2.0;
    s.sun.enabled = true;
    s.sun.direction = normalized(Vec3{0.5, 0.3, -0.8});
    s.sun.irradiance = {1.0, 0.95, 0.85};
    s.sky.radiance = {0.03, 0.05, 0.09};
    s.sky.directions = 3;
    s.light.method = LightSpec::Method::exact;
    s.background.color = {0.0, 0.0, 0.0};  // the sums below measure the volume only
    return s;
}

struct ModelRun {
    Image image;
    DiffuseSolution diffuse;
};

ModelRun run_model(MPI_Comm comm, const Scene& s, const std::string& name, double step_growth = 1.0) {
    World w = make_world(comm, s);
    Report report;
    w.light = compute_light_transport(*w.d, w.medium, make_lights(s), report, {}, s.light.method);
    const SolveContext ctx{s, *w.d, w.medium, w.light, report};
    ModelRun out;
    if (name == "psf") {
        PsfOptions opt;
        opt.step_growth = step_growth;
        auto model = make_psf_model(opt);
        model->solve(ctx, out.diffuse);
        out.image = model->render(ctx);
    } else {
        out.image = render_image(RenderInputs{s, w.medium, w.light, w.none}, *w.d, report);
    }
    return out;
}

TEST(PsfModel, ImageIndependentOfRanksAndBrighterThanSingleScattering) {
    const Scene s = cloud_scene();
    const ModelRun a = run_model(MPI_COMM_WORLD, s, "psf");
    const ModelRun b = run_model(MPI_COMM_SELF, s, "psf");
    const ModelRun single = run_model(MPI_COMM_SELF, s, "single");
    const ModelRun dense = run_model(MPI_COMM_SELF, s, "psf", 0.0);
    const ModelRun fine = run_model(MPI_COMM_SELF, s, "psf", 0.25);
    if (rank() != 0) return;
    double peak = 0.0;
    const double diff = max_rel_diff(a.image, b.image, peak);
    double sum_psf = 0, sum_single = 0, sum_dense = 0, sum_fine = 0;
    for (size_t i = 0; i < b.image.rgba.size(); i += 4)
        for (int c = 0; c < 3; ++c) {
            sum_psf += b.image.rgba[i + c] - single.image.rgba[i + c];
            sum_dense += dense.image.rgba[i + c] - single.image.rgba[i + c];
            sum_fine += fine.image.rgba[i + c] - single.image.rgba[i + c];
            sum_single += single.image.rgba[i + c];
        }
    std::printf("  psf: max |world - self| / peak = %.3g; MS adds %.1f%% (step_growth 1) / %.1f%% (0.25) / "
                "%.1f%% (every step) to single\n",
                diff, 100.0 * sum_psf / sum_single, 100.0 * sum_fine / sum_single, 100.0 * sum_dense / sum_single);
    EXPECT_LE(diff, 1e-5);
    // The MS term's level (35% of single scattering here): a factor of 2 anywhere in H (the
    // angular table itself is checked against G(l) in PsfKernels.RenderTableIntegratesToG)
    // gives 18% or 70% and fails.
    EXPECT_GT(sum_psf, 0.25 * sum_single);
    EXPECT_LT(sum_psf, 0.5 * sum_single);
    // Held samples converge to sampling every step as the spacing shrinks (on this 24-cell
    // cloud the blur widths are a few cells, so spacing 2w holds H over several cells: the
    // default step_growth 1 is 20% low here, 2% on the default 96-cell cumulus image).
    EXPECT_NEAR(sum_fine / sum_dense, 1.0, 0.05);
    EXPECT_LT(std::abs(sum_fine - sum_dense), std::abs(sum_psf - sum_dense));
}

// A band's image is its own: the view-ray sample points (psf_source.h) are set by the bands that
// scatter, whatever their order, so permuting the bands permutes the channels, and a band that
// does not scatter changes nothing in the others. (Band 0 alone set them before: a first band
// of sigma_t = 0 changed another band's image by 18% of its peak in a QA case.) The model's
// image has channel c = band c (the pipeline's reordering by name is not involved); early
// termination, which looks at every band, is off.
TEST(PsfModel, BandImagesDoNotDependOnTheBandsOrderNorOnABandThatDoesNotScatter) {
    Scene s = cloud_scene();
    s.render.early_termination = 0.0;
    const BandOptics u{"u", 1.0, 0.99, 0.85}, v{"v", 1.0, 0.99, 0.85}, w{"w", 1.1, 0.98, 0.8};
    s.bands = {u, v, w};
    const ModelRun uvw = run_model(MPI_COMM_WORLD, s, "psf");
    Scene p = s;  // the same bands as w, u, v
    p.bands = {w, u, v};
    p.sun.irradiance = {0.85, 1.0, 0.95};
    p.sky.radiance = {0.09, 0.03, 0.05};
    const ModelRun wuv = run_model(MPI_COMM_WORLD, p, "psf");
    Scene n = s;  // u's place taken by a band that does not scatter
    n.bands = {BandOptics{"n", 0.0, 0.99, 0.85}, v, w};
    const ModelRun nvw = run_model(MPI_COMM_WORLD, n, "psf");
    if (rank() != 0) return;
    // Channel c of image a against channel cb of image b, relative to b's channel peak.
    auto channel_diff = [](const Image& a, int ca, const Image& b, int cb) {
        double worst = 0.0, peak = 0.0;
        for (size_t i = 0; i < b.rgba.size(); i += 4) {
            peak = std::max(peak, static_cast<double>(std::abs(b.rgba[i + static_cast<size_t>(cb)])));
            worst = std::max(worst, static_cast<double>(std::abs(a.rgba[i + static_cast<size_t>(ca)] -
                                                                 b.rgba[i + static_cast<size_t>(cb)])));
        }
        EXPECT_GT(peak, 0.0);
        return worst / peak;
    };
    const double order[3] = {channel_diff(wuv.image, 1, uvw.image, 0), channel_diff(wuv.image, 2, uvw.image, 1),
                             channel_diff(wuv.image, 0, uvw.image, 2)};
    const double beside[2] = {channel_diff(nvw.image, 1, uvw.image, 1), channel_diff(nvw.image, 2, uvw.image, 2)};
    std::printf("  psf bands: permuted %.2e %.2e %.2e, beside a non-scattering band %.2e %.2e (of the peak)\n",
                order[0], order[1], order[2], beside[0], beside[1]);
    for (double d : order) EXPECT_LE(d, 1e-6);
    for (double d : beside) EXPECT_LE(d, 1e-6);
}

// The light pass and the psf model's equivalent fluence of scene s on w (collective).
DiffuseSolution psf_fluence(const Scene& s, World& w) {
    Report report;
    w.light = compute_light_transport(*w.d, w.medium, make_lights(s), report, {}, s.light.method);
    DiffuseSolution out;
    make_psf_model(PsfOptions{})->solve(SolveContext{s, *w.d, w.medium, w.light, report}, out);
    return out;
}

TEST(PsfModel, FluenceIndependentOfRanksAndPositiveInTheCloud) {
    const Scene s = cloud_scene();
    World w = make_world(MPI_COMM_WORLD, s), ws = make_world(MPI_COMM_SELF, s);
    const DiffuseSolution world = psf_fluence(s, w), self = psf_fluence(s, ws);
    ASSERT_EQ(world.fluence.size(), 3u);
    double worst = 0, peak = 0;
    long positive = 0, cells = 0;
    for_each_cell(w.d->local(), [&](int i, int j, int k) {
        const double a = world.fluence[0](i, j, k), b = self.fluence[0](i, j, k);
        worst = std::max(worst, std::abs(a - b));
        peak = std::max(peak, b);
        if (w.medium.rho(i, j, k) > 0) ++cells, positive += a > 0;
    });
    EXPECT_LE(worst, 1e-6 * peak);
    EXPECT_EQ(positive, cells);
}

// The absolute size of the equivalent fluence (a wrong E0, 4π, factor 2 or sign of g fails):
// an optically thin uniform medium under an overhead sun E0. At depth tau_rho below the top, the
// scattering depth to the sun is l2 = sigma_s tau_rho << 1, the light volume is laterally uniform
// and nearly 1, so fluence = E0 T G(l2) with G(l) -> l (1+g)/(1-g) (README: the thin-medium
// limit of eq. 17, (1+g)/(1-g) times the singly scattered light's l).
TEST(PsfModel, ThinMediumFluenceIsE0TTimesTheSmallLLimitOfG) {
    Scene s = base_scene();
    s.grid.n = {16, 16, 16};
    s.grid.cell_size = 1.0;
    s.medium.kind = MediumSpec::Kind::box;
    s.bands = {BandOptics{"gray", 1e-4, 0.5, 0.3}};
    s.sun.enabled = true;
    s.sun.direction = {0.0, 0.0, -1.0};
    s.sun.irradiance = {2.0};
    World w = make_world(MPI_COMM_WORLD, s);
    const DiffuseSolution out = psf_fluence(s, w);
    const double g = 0.3, sigma_s = 0.5e-4;
    double worst = 0.0;
    for_each_cell(w.d->local(), [&](int i, int j, int k) {
        const double tau_rho = 16.0 - (k + 0.5);  // rho = 1, h = 1 m
        const double l2 = sigma_s * tau_rho;
        const double expect = 2.0 * std::exp(-1e-4 * tau_rho) * l2 * (1 + g) / (1 - g);
        worst = std::max(worst, std::abs(out.fluence[0](i, j, k) / expect - 1.0));
    });
    MPI_Allreduce(MPI_IN_PLACE, &worst, 1, MPI_DOUBLE, MPI_MAX, w.d->comm());
    if (rank() == 0) std::printf("    thin medium: max |fluence / (E0 T l2 (1+g)/(1-g)) - 1| = %.2e\n", worst);
    EXPECT_LT(worst, 0.01);
}

}  // namespace
}  // namespace nimbus
