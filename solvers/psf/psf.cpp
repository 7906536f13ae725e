#include "solvers/psf/psf.h"

#include <algorithm>
#include <vector>

#include "solvers/psf/psf_source.h"
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
        {
            ScopedTimer t(ctx.report, "psf_pyramid");
            source_ = std::make_unique<psf::PsfSource>(ctx, opt_);
        }
        ScopedTimer t(ctx.report, "psf_fluence");
        out = DiffuseSolution{};
        source_->fluence(ctx.medium, ctx.decomp, out.fluence);
        auto& v = ctx.report.values()["psf"];
        v["levels"] = source_->pyramid().size();
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
    // The Gaussian pyramids: ~30 bytes per local cell per light volume (light terms x bands of
    // different sigma_t), measured on the default cloud: 271 bytes at 9 terms, ~540 at 17.
    double memory_bytes(const Scene& s, const Decomposition& d, int nlights) const override {
        std::vector<double> sigma;
        for (const BandOptics& b : s.bands)
            if (std::find(sigma.begin(), sigma.end(), b.sigma_t) == sigma.end()) sigma.push_back(b.sigma_t);
        return 30.0 * nlights * static_cast<double>(sigma.size()) * static_cast<double>(d.local().cells());
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
