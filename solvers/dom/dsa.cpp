#include "solvers/dom/dsa.h"

#include <fmt/format.h>

#include <cmath>

#include "solvers/diffusion/solve_region.h"
#include "src/core/error.h"
#include "src/core/halo.h"

namespace nimbus::dom {
namespace {

double global_norm(const std::vector<double>& v, MPI_Comm comm) {
    double s = 0.0;
    for (double a : v) s += a * a;
    MPI_Allreduce(MPI_IN_PLACE, &s, 1, MPI_DOUBLE, MPI_SUM, comm);
    return std::sqrt(s);
}

}  // namespace

DiffusionSynthetic::DiffusionSynthetic(const Decomposition& d, const BandProblem& p, double tolerance,
                                       const std::array<bool, 6>& reflective, bool lagged_sources)
    : d_(d), p_(p) {
    const Box& own = d.local();
    dp_.h = p.h;
    dp_.n = d.global().hi;
    dp_.periodic = {d.periodic(0), d.periodic(1), d.periodic(2)};
    // Zero current on the mirror faces; on the high ones only with their lagged current changes
    // as sources (dsa.h).
    for (size_t f = 0; f < 6; ++f) dp_.reflective[f] = reflective[f] && (f % 2 == 0 || lagged_sources);
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
    delta_ = Field<double>(own, 0, 1, 0.0);
    if (region_.box.empty()) return;  // same answer on every rank: nothing is set up anywhere
    kappa_floor_ = 1.0 / diffusion::default_transport_length(region_, dp_);

    // Assemble the matrix and set up PFMG-PCG once (collective; see linear_solve.h).
    namespace hy = diffusion::hypre;
    const diffusion::Assembler assembler(dp_, kappa_floor_);
    box_ = own.intersect(region_.box);
    Int3 period{0, 0, 0};
    for (int a = 0; a < 3; ++a) period[a] = (dp_.periodic[a] && dp_.n[a] > 1) ? dp_.n[a] : 0;
    grid_ = std::make_unique<hy::Grid>(d.comm(), box_, period);
    stencil_ = std::make_unique<hy::SymmetricStencil7>();
    A_ = std::make_unique<hy::Matrix>(d.comm(), *grid_, *stencil_);
    const size_t ncell = static_cast<size_t>(box_.cells());
    std::vector<double> values(ncell * hy::SymmetricStencil7::kEntries);
    full_.assign(ncell, 0);
    size_t n = 0, c = 0;
    for_each_cell(box_, [&](int i, int j, int k) {
        const diffusion::CellRow row = assembler.row(i, j, k);
        values[n++] = row.diag;
        values[n++] = -row.coupling[diffusion::kXm];
        values[n++] = -row.coupling[diffusion::kYm];
        values[n++] = -row.coupling[diffusion::kZm];
        full_[c++] = assembler.full(i, j, k) ? 1 : 0;
    });
    A_->set_box_values(box_, values);
    A_->assemble();
    b_ = std::make_unique<hy::Vector>(d.comm(), *grid_);
    x_ = std::make_unique<hy::Vector>(d.comm(), *grid_);
    r_ = std::make_unique<hy::Vector>(d.comm(), *grid_);
    b_->assemble();
    x_->assemble();
    solver_ = std::make_unique<hy::Solver>(d.comm(), opt_.solver, period[0] + period[1] + period[2] > 0);
    solver_->set_max_iterations(opt_.max_iterations);  // the largest limit, before setup
    solver_->set_tolerance(opt_.tolerance);
    solver_->setup(*A_, *b_, *x_);
}

DiffusionSynthetic::~DiffusionSynthetic() = default;

int DiffusionSynthetic::correct(const Field<double>& fluence_old, Field<double>& fluence,
                                const Field<double>* mirror_source) {
    const Box& own = d_.local();
    if (change_.owned().empty()) change_ = Field<double>(own, 0, 1, 0.0);
    for_each_cell(own, [&](int i, int j, int k) { change_(i, j, k) = fluence(i, j, k) - fluence_old(i, j, k); });
    const int iterations = solve(change_, mirror_source);
    for_each_cell(own, [&](int i, int j, int k) { fluence(i, j, k) += delta_(i, j, k); });
    return iterations;
}

int DiffusionSynthetic::solve(const Field<double>& r, const Field<double>* mirror_source) {
    delta_.fill(0.0);
    if (!solver_) return 0;
    // b = h² (sigma_s r + dJ/h on high mirror faces) in full cells, 0 in empty ones:
    // Assembler::rhs with Q0 = sigma_s r and G = 0 (no face terms).
    const size_t ncell = static_cast<size_t>(box_.cells());
    const double h2 = p_.h * p_.h;
    std::vector<double> b(ncell);
    size_t n = 0;
    for_each_cell(box_, [&](int i, int j, int k) {
        const double extra = mirror_source ? (*mirror_source)(i, j, k) : 0.0;
        b[n] = full_[n] ? h2 * (p_.sigma_s(i, j, k) * r(i, j, k) + extra) : 0.0;
        ++n;
    });
    const double b_norm = global_norm(b, d_.comm());
    if (b_norm == 0.0) return 0;
    std::vector<double> x(ncell, 0.0), rv;
    b_->set_box_values(box_, b);
    b_->assemble();
    x_->set_box_values(box_, x);
    x_->assemble();
    // Solve; restart from the current x while the TRUE residual ||b - A x|| / ||b|| is above
    // the tolerance (PCG's recursive residual can understate it), as solve_with_hypre does.
    int iterations = 0, left = opt_.max_iterations;
    double tol_round = opt_.tolerance, true_res = 0.0;
    bool ok = false;
    for (int round = 0; round < 6 && left > 0; ++round) {
        solver_->set_tolerance(tol_round);
        solver_->set_max_iterations(left);
        solver_->solve(*A_, *b_, *x_);
        const int its = solver_->iterations();
        iterations += its;
        left -= its;
        r_->set_box_values(box_, b);
        r_->assemble();
        diffusion::hypre::matvec(-1.0, *A_, *x_, 1.0, *r_);
        r_->get_box_values(box_, rv);
        true_res = global_norm(rv, d_.comm()) / b_norm;
        if (true_res <= opt_.tolerance) {
            ok = true;
            break;
        }
        if (!std::isfinite(true_res)) break;
        tol_round *= 0.5 * opt_.tolerance / true_res;
    }
    if (!ok)  // true_res is global: every rank throws together
        throw Error(fmt::format("dom: DSA diffusion solve did not reach {:.1e} in {} iterations (true residual {:.3e})",
                                opt_.tolerance, iterations, true_res));
    x_->get_box_values(box_, x);
    n = 0;
    for_each_cell(box_, [&](int i, int j, int k) {
        if (full_[n]) delta_(i, j, k) = x[n];
        ++n;
    });
    return iterations;
}

}  // namespace nimbus::dom
