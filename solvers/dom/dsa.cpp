#include "solvers/dom/dsa.h"

#include <cmath>

#include "solvers/diffusion/linear_solve.h"
#include "solvers/diffusion/solve_region.h"
#include "src/core/halo.h"

namespace nimbus::dom {

DiffusionSynthetic::DiffusionSynthetic(const Decomposition& d, const BandProblem& p, double tolerance)
    : d_(d), p_(p) {
    const Box& own = d.local();
    dp_.h = p.h;
    dp_.n = d.global().hi;
    dp_.periodic = {d.periodic(0), d.periodic(1), d.periodic(2)};
    dp_.kappa_tr = Field<double>(own, 1, 1, 0.0);
    dp_.sigma_a = Field<double>(own, 0, 1, 0.0);
    // D = 1/(3 kappa_tr) + h/4 (dsa.h): kappa_tr of the diffusion assembly is 1/(3 D).
    for_each_cell(own, [&](int i, int j, int k) {
        const double kt = p.kappa_tr(i, j, k);
        dp_.kappa_tr(i, j, k) = kt > 0.0 ? 1.0 / (1.0 / kt + 0.75 * p.h) : 0.0;
        dp_.sigma_a(i, j, k) = p.sigma_a(i, j, k);
    });
    exchange_halo(dp_.kappa_tr, d);
    dp_.Q0.emplace_back(own, 0, 1, 0.0);
    dp_.G.emplace_back(own, 1, 3, 0.0);
    opt_.solver = "pfmg-pcg";
    opt_.tolerance = tolerance;
    opt_.max_iterations = 200;
    region_ = diffusion::find_solve_region(d, dp_, opt_.margin);
    if (!region_.box.empty()) kappa_floor_ = 1.0 / diffusion::default_transport_length(region_, dp_);
    delta_ = Field<double>(own, 0, 1, 0.0);
}

int DiffusionSynthetic::correct(const Field<double>& fluence_old, Field<double>& fluence, Report& report) {
    const Box& own = d_.local();
    delta_.fill(0.0);
    double norm = 0.0;
    for_each_cell(own, [&](int i, int j, int k) {
        const double r = p_.sigma_s(i, j, k) * (fluence(i, j, k) - fluence_old(i, j, k));
        dp_.Q0[0](i, j, k) = r;
        norm += r * r;
    });
    MPI_Allreduce(MPI_IN_PLACE, &norm, 1, MPI_DOUBLE, MPI_SUM, d_.comm());
    if (norm == 0.0 || region_.box.empty()) return 0;
    const diffusion::Assembler assembler(dp_, kappa_floor_);
    const auto lin = diffusion::solve_with_hypre(d_, assembler, dp_, region_, opt_, report);
    size_t n = 0;
    for_each_cell(lin.box, [&](int i, int j, int k) {
        const double x = lin.x[0][n++];
        if (assembler.full(i, j, k)) delta_(i, j, k) = x;
    });
    for_each_cell(own, [&](int i, int j, int k) { fluence(i, j, k) += delta_(i, j, k); });
    return lin.stats[0].iterations;
}

}  // namespace nimbus::dom
