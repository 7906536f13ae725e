#include "solvers/diffusion/solve_diffusion.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "solvers/diffusion/assemble.h"
#include "solvers/diffusion/flux_limiter.h"
#include "solvers/diffusion/linear_solve.h"
#include "solvers/diffusion/solve_region.h"
#include "src/core/anderson.h"
#include "src/core/convergence_outlook.h"
#include "src/core/error.h"
#include "src/core/halo.h"
#include "src/core/log.h"
#include "src/core/progress.h"
#include "src/core/report.h"

namespace nimbus::diffusion {
namespace {

// One linear solve of p (all right-hand sides share the matrix). Its report entries
// (diffusion.systems) name the right-hand side, first_rhs + r, and the flux limiter's iteration
// (0: the P1 start) when limiter_iteration >= 0. known_floor: the transport cap's floor of p's
// full cells when the caller has it (the flux limiter's iterates keep the empty cells, so the
// pieces); then res.kappa_floor stays empty.
DiffusionResult solve_linear(const Decomposition& d, const DiffusionProblem& p,
                             const DiffusionOptions& opt, Report& report, size_t first_rhs = 0,
                             int limiter_iteration = -1, const TransportFloor* known_floor = nullptr) {
    const size_t nrhs = p.Q0.size();
    DiffusionResult res;
    {
        ScopedTimer t(report, "region");  // the solve region, and the cloud's pieces for the cap
        res.region = find_solve_region(d, p, opt.margin);
        // Cap of the transport mean free path (diffusion_kernel.h): the option, or each piece's size.
        if (!known_floor) res.kappa_floor = transport_floor(d, p, res.region, opt.max_transport_length);
    }
    const TransportFloor& floor = known_floor ? *known_floor : res.kappa_floor;
    res.stats.resize(nrhs);
    // U and F are allocated after the linear solve (below), when hypre's matrix, vectors and
    // multigrid hierarchy are gone: the phase's peak memory is the solve's.
    const auto allocate_fields = [&] {
        for (size_t r = 0; r < nrhs; ++r) {
            res.U.emplace_back(d.local(), 1, 1, 0.0);
            res.flux.emplace_back(d.local(), 1, 3, 0.0);
        }
    };

    auto& rec = report.values()["diffusion"];
    rec["solver"] = opt.solver;
    rec["tolerance"] = opt.tolerance;
    rec["region"] = {{"lo", res.region.box.lo}, {"hi", res.region.box.hi},
                     {"cells", res.region.cells()}};
    if (res.region.box.empty() || nrhs == 0) {  // nothing scatters, or nothing lights it
        allocate_fields();
        return res;
    }

    rec["kappa_tr_floor"] = floor.largest;
    if (floor.pieces >= 0) rec["pieces"] = floor.pieces;
    const Assembler assembler(p, floor);
    LinearSolveOutput lin = opt.solver == "petsc"
                                ? solve_with_petsc(d, assembler, p, res.region, opt, report)
                                : solve_with_hypre(d, assembler, p, res.region, opt, report);
    ScopedTimer flux_timer(report, "flux");  // U on the local box, F = 4π(G - D grad U), clamping
    allocate_fields();
    for (size_t r = 0; r < nrhs; ++r) {
        size_t n = 0;
        for_each_cell(lin.box, [&](int i, int j, int k) {
            const double u = lin.x[r][n++];
            res.U[r](i, j, k) = assembler.full(i, j, k) ? u : 0.0;
        });
        exchange_halo(res.U[r], d);
        // Outside the region every cell is empty, and F there stays 0.
        for_each_cell(res.region.box.intersect(d.local()), [&](int i, int j, int k) {
            const Vec3 F = assembler.flux(static_cast<int>(r), res.U[r], i, j, k);
            for (int c = 0; c < 3; ++c) res.flux[r](i, j, k, c) = F[c];
        });
        exchange_halo(res.flux[r], d);
        res.stats[r] = lin.stats[r];
        SolveStats& st = res.stats[r];
        std::int64_t neg[2] = {0, 0}, gneg[2];
        double umin[2] = {0.0, 0.0}, gumin[2], umax = 0.0;
        for_each_cell(res.region.box.intersect(d.local()), [&](int i, int j, int k) {  // U = 0 outside
            double& u = res.U[r](i, j, k);
            umax = std::max(umax, u);
            if (u >= 0.0) return;
            const int c = assembler.has_marshak_face(i, j, k) ? 0 : 1;
            ++neg[c];
            umin[c] = std::min(umin[c], u);
            if (opt.clamp_negative) u = 0.0;
        });
        MPI_Allreduce(neg, gneg, 2, MPI_INT64_T, MPI_SUM, d.comm());
        MPI_Allreduce(umin, gumin, 2, MPI_DOUBLE, MPI_MIN, d.comm());
        MPI_Allreduce(MPI_IN_PLACE, &umax, 1, MPI_DOUBLE, MPI_MAX, d.comm());
        st.max_U = umax;
        st.min_U = std::min(gumin[0], gumin[1]);
        st.min_U_interior = gumin[1];
        st.negative_boundary_cells = gneg[0];
        st.negative_interior_cells = gneg[1];
        if (opt.clamp_negative && gneg[0] + gneg[1] > 0) exchange_halo(res.U[r], d);
        nlohmann::json entry = {{"rhs", first_rhs + r},
                                {"iterations", st.iterations},
                                {"restarts", st.restarts},
                                {"reported_residual", st.reported_residual},
                                {"true_residual", st.true_residual},
                                {"assemble_seconds", st.assemble_seconds},
                                {"setup_seconds", st.setup_seconds},
                                {"solve_seconds", st.solve_seconds},
                                {"negative_boundary_cells", st.negative_boundary_cells},
                                {"negative_interior_cells", st.negative_interior_cells},
                                {"min_U", st.min_U},
                                {"min_U_interior", st.min_U_interior},
                                {"max_U", st.max_U}};
        if (limiter_iteration >= 0) entry["limiter_iteration"] = limiter_iteration;
        rec["systems"].push_back(std::move(entry));
    }
    return res;
}

// Flux-limited diffusion (flux_limiter.h) for right-hand side r alone (lambda depends on U):
// fixed-point iteration on kappa_eff = kappa_tr / (3 lambda), lambda = lambda(R) of the previous
// iterates, until the largest change of U relative to max U is below opt.limiter_tolerance
// (twice in a row after the first iteration).
// progress: the run's line over all right-hand sides, of which r are done in done_seconds.
void solve_limited_rhs(const Decomposition& d, const DiffusionProblem& p, size_t r,
                       const DiffusionOptions& opt, Report& report, DiffusionResult& out, Progress& progress,
                       double done_seconds) {
    const double start = wall_time();
    DiffusionProblem q;  // p with right-hand side r only (every member but Q0, G and escape_flux copied)
    q.h = p.h;
    q.n = p.n;
    q.periodic = p.periodic;
    q.rhs_within = p.rhs_within;  // where G lives: its halo exchange must skip the ranks outside it
    q.reflective = p.reflective;
    q.kappa_tr = p.kappa_tr;
    q.sigma_a = p.sigma_a;
    q.Q0 = {p.Q0[r]};
    q.G = {p.G[r]};
    if (!p.escape_flux.empty()) q.escape_flux = {p.escape_flux[r]};
    DiffusionResult res = solve_linear(d, q, opt, report, r, 0);  // P1 with the cap: the first iterate
    const TransportFloor floor = std::move(res.kappa_floor);      // the same for every iterate
    std::vector<double> history;
    double first_seconds = 0.0;
    int linear_iterations = res.stats[0].iterations;
    bool converged = false;
    // Anderson acceleration (src/core/anderson.h) of lambda <- lambda(R(U(lambda))), depth 5,
    // undamped at first: the first step is then a plain Picard step. A damped first step (the old
    // lambda <- (lambda + lambda(R)) / 2) can leave every cell's kappa_tr / (3 lambda) below the
    // cap's floor, so U does not move and the change test stops far from the fixed point
    // (test_flux_limiter.cpp, the thin cube). On the cumulus at tolerance 1e-3: 12 iterations
    // and 1.4e-4 rel. L2 from the fixed point, against 31 and 3.6e-4 damped.
    // Undamped Anderson wanders on hard cases (no delta scaling, g = 0.85, 48 x 48 x 32 cloud:
    // changes 2e-3 to 1e-1 for 80 iterations); mixing 0.5 from the 16th iteration on converges
    // there in 28-36 iterations, and the common cases stop before it (cumulus: 6 at 1e-2).
    constexpr int kUndampedIterations = 15;
    constexpr double kLateMixing = 0.5;
    AndersonMixer mixer(d.comm(), 5, 1.0);
    const double lambda_min = levermore_pomraning(kMaxKnudsen);
    std::vector<double> lambda, target;  // lambda_n and lambda(R(U_n)) of the cells with kappa_tr > 0
    for (int it = 0; it < opt.limiter_iterations && !converged; ++it) {
        lambda.clear();
        target.clear();
        for_each_cell(d.local(), [&](int i, int j, int k) {
            const double kt = p.kappa_tr(i, j, k);
            if (kt <= 0.0) return;
            const double kc = std::max(q.kappa_tr(i, j, k), floor.at(i, j, k));
            const double* F = &res.flux[0](i, j, k);
            const double Fn = std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]);
            lambda.push_back(kt / (3.0 * q.kappa_tr(i, j, k)));
            target.push_back(levermore_pomraning(knudsen_number(res.U[0](i, j, k), Fn, kt, kc)));
        });
        lambda = mixer.next(lambda, target);
        if (it + 1 == kUndampedIterations) mixer.set_mixing(kLateMixing);
        size_t n = 0;
        for_each_cell(d.local(), [&](int i, int j, int k) {
            const double kt = p.kappa_tr(i, j, k);
            if (kt <= 0.0) return;
            const double l = std::clamp(lambda[n++], lambda_min, 1.0 / 3.0);
            q.kappa_tr(i, j, k) = kt / (3.0 * l);
            for (int c = 0; c < 3; ++c) q.G[0](i, j, k, c) = 3.0 * l * p.G[r](i, j, k, c);
        });
        exchange_halo(q.kappa_tr, d);
        exchange_rhs_halo(q, q.G[0], d);
        const Field<double> previous = res.U[0];
        // The cap stays: without it the Picard iteration oscillated (no convergence in 30
        // iterations) on a cube of optical thickness 0.2, where lambda -> 1/R everywhere.
        res = solve_linear(d, q, opt, report, r, it + 1, &floor);
        linear_iterations += res.stats[0].iterations;
        double local[2] = {0.0, 0.0}, global[2];
        for_each_cell(d.local(), [&](int i, int j, int k) {
            local[0] = std::max(local[0], std::abs(res.U[0](i, j, k) - previous(i, j, k)));
            local[1] = std::max(local[1], std::abs(res.U[0](i, j, k)));
        });
        MPI_Allreduce(local, global, 2, MPI_DOUBLE, MPI_MAX, d.comm());
        history.push_back(global[1] > 0.0 ? global[0] / global[1] : 0.0);
        // The first step is plain Picard from P1: its change is the fixed-point residual. Later
        // Anderson steps mix the history, and a single small change can be luck in an iteration
        // that wanders (the hard case above: one change of 6.2e-3 among them stopped it at 1e-2,
        // 0.7% rel. L2 from the answer): those need two in a row.
        const size_t h = history.size();
        converged = history[h - 1] < opt.limiter_tolerance &&
                    (h == 1 || history[h - 2] < opt.limiter_tolerance);
        const int nrhs = static_cast<int>(p.Q0.size());
        const double seconds = wall_time() - start;
        if (h == 1) first_seconds = seconds;  // the first iteration carries the P1 solve before it
        const RunOutlook o = run_outlook(history, opt.limiter_tolerance, seconds, first_seconds, static_cast<int>(r),
                                         done_seconds, nrhs);
        progress.update(o.fraction * nrhs, o.seconds_left, fmt::format("limiter tolerance {:g}", opt.limiter_tolerance),
                        fmt::format("right-hand side {} of {}, iteration {}, relative change of U {:.2e}", r + 1,
                                    nrhs, h, history.back()));
        log::debug("diffusion: flux limiter, right-hand side {} iteration {}: relative change of U {:.3e} "
                   "({} Anderson columns, mixing {:g}, {} {} iterations)",
                   r, h, history.back(), mixer.columns_used(), it < kUndampedIterations ? 1.0 : kLateMixing,
                   res.stats[0].iterations, opt.solver);
    }
    if (!converged && opt.limiter_iterations > 0) {
        const size_t h = history.size();
        const std::string changes =
            h <= 10 ? fmt::format("{:.2e}", fmt::join(history, ", "))
                    : fmt::format("{:.2e}, ..., {:.2e}", fmt::join(history.begin(), history.begin() + 3, ", "),
                                  fmt::join(history.end() - 6, history.end(), ", "));
        throw Error(fmt::format("flux-limited diffusion did not converge to limiter_tolerance = {:g} in {} "
                                "iterations (model.diffusion.limiter_iterations); relative changes of U: {}",
                                opt.limiter_tolerance, opt.limiter_iterations, changes));
    }
    report.values()["diffusion"]["flux_limiter"].push_back(
        {{"picard_iterations", history.size()}, {"linear_solves", history.size() + 1},
         {"linear_iterations", linear_iterations},
         {"relative_changes", history}, {"anderson_restarts", mixer.restarts()}});
    out.region = res.region;
    out.U.push_back(std::move(res.U[0]));
    out.flux.push_back(std::move(res.flux[0]));
    out.stats.push_back(res.stats[0]);
}

}  // namespace

DiffusionResult solve_diffusion(const Decomposition& d, const DiffusionProblem& p,
                                const DiffusionOptions& opt, Report& report) {
    if (opt.flux_limiter == "none") return solve_linear(d, p, opt, report);
    DiffusionResult out;
    // Progress (rank 0, from 2 s on): right-hand sides done plus the current one's way to the
    // limiter's tolerance, ETA from its convergence rate (src/core/convergence_outlook.h).
    Progress progress("diffusion flux limiter", static_cast<double>(p.Q0.size()), d.rank() == 0);
    const double start = wall_time();
    for (size_t r = 0; r < p.Q0.size(); ++r) solve_limited_rhs(d, p, r, opt, report, out, progress, wall_time() - start);
    progress.finish();
    if (p.Q0.empty()) out.region = find_solve_region(d, p, opt.margin);
    return out;
}

}  // namespace nimbus::diffusion
