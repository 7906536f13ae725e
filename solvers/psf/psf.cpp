#include "solvers/psf/psf.h"

#include <algorithm>
#include <vector>

#include "solvers/psf/psf_source.h"
#include "src/core/log.h"
#include "src/core/report.h"
#include "src/physics/lights.h"
#include "src/render/raycaster.h"

namespace nimbus {
namespace {

class PsfModel final : public ScatteringModel {
public:
    explicit PsfModel(const PsfOptions& opt) : opt_(opt) {}
    std::string name() const override { return "psf"; }
    nlohmann::json options() const override { return options_json(opt_); }

    void solve(const SolveContext& ctx, DiffuseSolution& out) override {
        out = DiffuseSolution{};
        if (ctx.light.lights.empty()) {
            // No light (sun off, no sky; the pipeline has warned): nothing to blur, every fluence
            // is zero and the image shows the background, as in the other models.
            out = zero_solution(ctx.decomp, ctx.medium.nbands());
            source_.reset();
            return;
        }
        {
            ScopedTimer t(ctx.report, "psf_pyramid");
            source_ = std::make_unique<psf::PsfSource>(ctx, opt_);
        }
        ScopedTimer t(ctx.report, "psf_fluence");
        source_->fluence(ctx.medium, ctx.decomp, out.fluence);
        auto& v = ctx.report.values()["psf"];
        v["levels"] = source_->pyramid().size();
        if (opt_.levels > source_->pyramid().size())
            log::warn("model.psf.levels = {}: this grid allows {} pyramid levels, and those are used", opt_.levels,
                      source_->pyramid().size());
        nlohmann::json widths = nlohmann::json::array();
        for (int k = 0; k < source_->pyramid().size(); ++k) widths.push_back(source_->pyramid().level(k).width);
        v["level_widths_m"] = widths;
    }

    void check_layout(const Decomposition& d) const override { psf::check_decomposition(d); }
    void check(const Scene& s, const Decomposition& d, const Medium& m) const override {
        psf::check_decomposition(d);
        psf::check_light_volumes(static_cast<int>(make_lights(s).size()), m.bands);
    }
    bool renders_image() const override { return true; }
    // Per rank, with C = light terms x groups of bands sharing sigma_t light volumes, nl light
    // terms, a slab of L layers of nx x ny cells, A = (nx + 6)(ny + 6) (level 0 carries 3 ghost
    // layers), B = (nx + 2)(ny + 2):
    //   kept       level 0 as float 4 A C (L + 6), the coarser levels (the same with 2^k fewer
    //              cells per axis), the light depths 2 nl floats on B (L + 2);
    //   then the larger of
    //   the build  level 0 as double 8 A C (L + 6), the medium's path lengths (nl doubles and
    //              the indicator on B (L + 2));
    //   the render about 36 bytes per pixel (the view-depth prepass of the march);
    //   plus, on more than one rank, the depths gathered over the layers a rank marches (about
    //   its slab + 4 layers, in fluence() and again at render).
    // Measured on the default cloud, estimate against peak (whole run): 96 x 96 x 64 at 1-4
    // ranks 308/271, 209/190, 164/151, 138/128 MiB; 48 x 48 x 32 86/89, 74/74, 70/66, 68/64.
    // (Until the thirty-sixth session 30 bytes per cell per light volume: 24-27% low at 2-4
    // ranks, where the gathered depths were not counted.)
    double memory_bytes(const Scene& s, const Decomposition& d, int nlights) const override {
        std::vector<double> sigma;
        for (const BandOptics& b : s.bands)
            if (std::find(sigma.begin(), sigma.end(), b.sigma_t) == sigma.end()) sigma.push_back(b.sigma_t);
        const double nl = nlights, C = nl * static_cast<double>(sigma.size());
        const Box box = d.local();
        const double nx = box.size(0), ny = box.size(1), L = box.size(2), nz = d.global().size(2);
        const double A = (nx + 6) * (ny + 6), B = (nx + 2) * (ny + 2);
        double levels = 0.0;
        for (double f = 2; nx / f >= 2 && ny / f >= 2; f *= 2)
            levels += 4 * C * (nx / f + 6) * (ny / f + 6) * (std::min(nz / f, L / f + 6) + 6);
        const double kept = 4 * A * C * (L + 6) + levels + 8 * nl * B * (L + 2);
        const double build = 8 * A * C * (L + 6) + (8 * nl + 8) * B * (L + 2);
        const double render = 36.0 * s.camera.width * s.camera.height;
        const double gathered = d.size() > 1 ? 8 * nl * nx * ny * (L + 4) : 0.0;
        return kept + std::max(build, render) + gathered;
    }
    Image render(const SolveContext& ctx) override {
        const DiffuseSolution none;  // multiple scattering comes from the PSF source
        RenderInputs in{ctx.scene, ctx.medium, ctx.light, none};
        in.view_source = source_.get();
        return render_image(in, ctx.decomp, ctx.report);
    }

private:
    PsfOptions opt_;
    std::unique_ptr<psf::PsfSource> source_;
};

}  // namespace

std::unique_ptr<ScatteringModel> make_psf_model(const PsfOptions& opt) { return std::make_unique<PsfModel>(opt); }

}  // namespace nimbus
