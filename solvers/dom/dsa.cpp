#include "solvers/dom/dsa.h"

#include <fmt/format.h>

#include <cmath>
#include <numbers>

#include "solvers/diffusion/solve_region.h"
#include "src/core/error.h"
#include "src/core/halo.h"

namespace nimbus::dom {
namespace {

// The 7-point matrix of a's rows on box (symmetric storage), assembled.
std::unique_ptr<diffusion::hypre::Matrix> assemble_matrix(MPI_Comm comm, const diffusion::Assembler& a, const Box& box,
                                                          const diffusion::hypre::Grid& grid,
                                                          const diffusion::hypre::SymmetricStencil7& stencil) {
    namespace hy = diffusion::hypre;
    auto A = std::make_unique<hy::Matrix>(comm, grid, stencil);
    std::vector<double> values(static_cast<size_t>(box.cells()) * hy::SymmetricStencil7::kEntries);
    size_t n = 0;
    for_each_cell(box, [&](int i, int j, int k) {
        const diffusion::CellRow row = a.row(i, j, k);
        values[n++] = row.diag;
        values[n++] = -row.coupling[diffusion::kXm];
        values[n++] = -row.coupling[diffusion::kYm];
        values[n++] = -row.coupling[diffusion::kZm];
    });
    A->set_box_values(box, values);
    A->assemble();
    return A;
}

}  // namespace

DiffusionSynthetic::DiffusionSynthetic(const Decomposition& d, const BandProblem& p,
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
    chi1_ = p.phase.chi.size() > 1 ? p.phase.chi[1] : 0.0;
    region_ = diffusion::find_solve_region(d, dp_, DiffusionOptions{}.margin);
    delta_ = Field<double>(own, 0, 1, 0.0);
    current_ = Field<double>(own, 0, 3, 0.0);
    if (region_.box.empty()) return;  // same answer on every rank: nothing is set up anywhere
    kappa_floor_ = diffusion::transport_floor(d, dp_, region_, 0.0);

    // Assemble the matrix and set up PFMG once (collective).
    namespace hy = diffusion::hypre;
    assembler_ = std::make_unique<diffusion::Assembler>(dp_, kappa_floor_);
    const diffusion::Assembler& assembler = *assembler_;
    box_ = own.intersect(region_.box);
    Int3 period{0, 0, 0};
    for (int a = 0; a < 3; ++a) period[a] = (dp_.periodic[a] && dp_.n[a] > 1) ? dp_.n[a] : 0;
    grid_ = std::make_unique<hy::Grid>(d.comm(), box_, period);
    stencil_ = std::make_unique<hy::SymmetricStencil7>();
    A_ = assemble_matrix(d.comm(), assembler, box_, *grid_, *stencil_);
    const size_t ncell = static_cast<size_t>(box_.cells());
    full_.assign(ncell, 0);
    size_t n = 0;
    for_each_cell(box_, [&](int i, int j, int k) { full_[n++] = assembler.full(i, j, k) ? 1 : 0; });
    b_ = std::make_unique<hy::Vector>(d.comm(), *grid_);
    x_ = std::make_unique<hy::Vector>(d.comm(), *grid_);
    b_->assemble();
    x_->assemble();
    solver_ = std::make_unique<hy::Solver>(d.comm(), "pfmg-cycle", period[0] + period[1] + period[2] > 0);
    solver_->set_max_iterations(kVCycles);  // "pfmg-cycle": tolerance 0, zero initial guess
    solver_->setup(*A_, *b_, *x_);
    period_ = period;  // the current's filter is set up at its first use (set_up_current_filter)
}

// The filter of the current's source (dsa.h): -∇·(nu ∇u) + kappa_tr u = kappa_tr G per
// component, nu = kCurrentFilterWidth / kappa*, as a diffusion problem (D = nu: kappa_tr of the
// assembly kappa* / (3 kCurrentFilterWidth)), Marshak at empty cells and the domain boundary, no
// flux through mirror faces; one PFMG V-cycle from zero (hypre::Solver "pfmg-cycle"), a linear map.
void DiffusionSynthetic::set_up_current_filter() {
    namespace hy = diffusion::hypre;
    const Box& own = d_.local();
    fp_.h = dp_.h;
    fp_.n = dp_.n;
    fp_.periodic = dp_.periodic;
    fp_.reflective = dp_.reflective;
    fp_.kappa_tr = Field<double>(own, 1, 1, 0.0);
    fp_.sigma_a = Field<double>(own, 0, 1, 0.0);
    for_each_cell(own, [&](int i, int j, int k) {
        if (p_.kappa_tr(i, j, k) <= 0.0) return;  // the same empty cells as the DSA problem
        fp_.kappa_tr(i, j, k) = p_.kappa(i, j, k) / (3.0 * kCurrentFilterWidth);
        fp_.sigma_a(i, j, k) = p_.kappa_tr(i, j, k);
    });
    exchange_halo(fp_.kappa_tr, d_);
    const diffusion::Assembler assembler(fp_, kappa_floor_);  // fp_ has dp_'s empty cells
    filter_A_ = assemble_matrix(d_.comm(), assembler, box_, *grid_, *stencil_);
    filter_ = std::make_unique<hy::Solver>(d_.comm(), "pfmg-cycle", period_[0] + period_[1] + period_[2] > 0);
    filter_->setup(*filter_A_, *b_, *x_);
}

// G <- the filtered G, component by component (owned cells of box_; 0 elsewhere).
void DiffusionSynthetic::filter_current_source(Field<double>& G) {
    const size_t ncell = static_cast<size_t>(box_.cells());
    const double h2 = p_.h * p_.h;
    std::vector<double> b(ncell), x(ncell);
    for (int c = 0; c < 3; ++c) {
        size_t n = 0;
        for_each_cell(box_, [&](int i, int j, int k) {
            b[n] = full_[n] ? h2 * p_.kappa_tr(i, j, k) * G(i, j, k, c) : 0.0;
            x[n++] = 0.0;
        });
        b_->set_box_values(box_, b);
        b_->assemble();
        x_->set_box_values(box_, x);
        x_->assemble();
        filter_->solve(*filter_A_, *b_, *x_);
        x_->get_box_values(box_, x);
        n = 0;
        for_each_cell(box_, [&](int i, int j, int k) {
            G(i, j, k, c) = full_[n] ? x[n] : 0.0;
            ++n;
        });
    }
}

DiffusionSynthetic::~DiffusionSynthetic() = default;

int DiffusionSynthetic::correct(const Field<double>& fluence_old, const Field<double>& flux_old,
                                Field<double>& fluence, Field<double>& flux, bool with_current,
                                const Field<double>* mirror_source) {
    if (change_.owned().empty()) {
        change_ = Field<double>(d_.local(), 0, 1, 0.0);
        flux_change_ = Field<double>(d_.local(), 0, 3, 0.0);
    }
    // Only box_ matters: outside it every cell is empty, so the sources there are zero and the
    // corrections stay zero (on the default cloud box_, with its margin, is 44% of the cells).
    for_each_cell(box_, [&](int i, int j, int k) {
        change_(i, j, k) = fluence(i, j, k) - fluence_old(i, j, k);
        for (int c = 0; c < 3; ++c) flux_change_(i, j, k, c) = flux(i, j, k, c) - flux_old(i, j, k, c);
    });
    const int iterations = solve(change_, with_current ? &flux_change_ : nullptr, mirror_source);
    for_each_cell(box_, [&](int i, int j, int k) {
        fluence(i, j, k) += delta_(i, j, k);
        for (int c = 0; c < 3; ++c) flux(i, j, k, c) += current_(i, j, k, c);
    });
    return iterations;
}

// x ≈ A^{-1} b on box_: kVCycles PFMG V-cycles from zero.
void DiffusionSynthetic::solve_system(std::vector<double>& b, std::vector<double>& x) {
    x.assign(b.size(), 0.0);
    b_->set_box_values(box_, b);
    b_->assemble();
    x_->set_box_values(box_, x);
    x_->assemble();
    solver_->solve(*A_, *b_, *x_);
    x_->get_box_values(box_, x);
}

int DiffusionSynthetic::solve(const Field<double>& r0, const Field<double>* r1, const Field<double>* mirror_source) {
    // delta_ and current_ are zero outside box_ from the constructor on; inside, every call
    // writes them (zero where the cell is empty or the right-hand side vanishes).
    if (!solver_) return 0;
    auto zero_box = [&](Field<double>& f) {
        for_each_cell(box_, [&](int i, int j, int k) {
            for (int c = 0; c < f.ncomp(); ++c) f(i, j, k, c) = 0.0;
        });
    };
    // Q0 = sigma_s R0 (+ dJ/h on high mirror faces), G = chi_1 sigma_s R1 / kappa_tr (physical
    // kappa_tr: dsa.h), filtered; b = Assembler::rhs (h² Q0 and G's face terms, 0 in empty
    // cells). Without the current: b = h² Q0 in full cells.
    const bool with_current = r1 != nullptr && chi1_ != 0.0;
    const size_t ncell = static_cast<size_t>(box_.cells());
    std::vector<double> b(ncell);
    size_t n = 0;
    if (with_current) {
        Field<double>& Q0 = dp_.Q0[0];
        Field<double>& G = dp_.G[0];
        for_each_cell(box_, [&](int i, int j, int k) {  // zero outside box_ (empty cells)
            Q0(i, j, k) = p_.sigma_s(i, j, k) * r0(i, j, k) + (mirror_source ? (*mirror_source)(i, j, k) : 0.0);
            const double kt = p_.kappa_tr(i, j, k);
            const double s = kt > 0.0 ? chi1_ * p_.sigma_s(i, j, k) / kt : 0.0;
            for (int c = 0; c < 3; ++c) G(i, j, k, c) = s * (*r1)(i, j, k, c);
        });
        if (!filter_) set_up_current_filter();  // collective: every rank passes r1 or none
        filter_current_source(G);
        exchange_halo(G, d_);
        for_each_cell(box_, [&](int i, int j, int k) { b[n++] = assembler_->rhs(0, i, j, k); });
    } else {
        const double h2 = p_.h * p_.h;
        for_each_cell(box_, [&](int i, int j, int k) {
            const double extra = mirror_source ? (*mirror_source)(i, j, k) : 0.0;
            b[n] = full_[n] ? h2 * (p_.sigma_s(i, j, k) * r0(i, j, k) + extra) : 0.0;
            ++n;
        });
    }
    const double b_norm = diffusion::hypre::global_norm(b, d_.comm());
    // iterate_band stops a non-finite fluence before DSA; this is the backstop (hypre would print
    // its own multi-line error for Inf or NaN input).
    if (!std::isfinite(b_norm))
        throw Error("dom: the DSA correction's right-hand side is not finite: the transport iteration diverges");
    if (b_norm == 0.0) {
        zero_box(delta_);
        zero_box(current_);
        return 0;
    }
    std::vector<double> x;
    solve_system(b, x);
    n = 0;
    for_each_cell(box_, [&](int i, int j, int k) {
        delta_(i, j, k) = full_[n] ? x[n] : 0.0;
        ++n;
    });
    if (with_current) {  // δF = G - D ∇δ: the assembly's flux 4π (G - D ∇U) of U = δ, over 4π
        if (delta_halo_.owned().empty()) delta_halo_ = Field<double>(d_.local(), 1, 1, 0.0);
        for_each_cell(box_, [&](int i, int j, int k) { delta_halo_(i, j, k) = delta_(i, j, k); });
        exchange_halo(delta_halo_, d_);
        for_each_cell(box_, [&](int i, int j, int k) {
            const Vec3 F = assembler_->flux(0, delta_halo_, i, j, k);
            for (int c = 0; c < 3; ++c) current_(i, j, k, c) = F[c] / (4.0 * std::numbers::pi);
        });
    } else {
        zero_box(current_);
    }
    return kVCycles;
}

}  // namespace nimbus::dom
