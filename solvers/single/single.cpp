#include "solvers/single/single.h"

namespace nimbus {
namespace {

class SingleScattering final : public ScatteringModel {
public:
    std::string name() const override { return "single"; }
    void solve(const SolveContext& ctx, DiffuseSolution& out) override {
        out = zero_solution(ctx.decomp, ctx.medium.nbands());
    }
};

}  // namespace

std::unique_ptr<ScatteringModel> make_single_model() { return std::make_unique<SingleScattering>(); }

}  // namespace nimbus
