// hypre back end of the diffusion model (linear_solve.h).
#include <cmath>
#include <optional>

#include <fmt/format.h>

#include "solvers/diffusion/hypre_struct.h"
#include "solvers/diffusion/linear_solve.h"
#include "src/core/log.h"
#include "src/core/error.h"
#include "src/core/residual_history.h"

namespace nimbus::diffusion {

LinearSolveOutput solve_with_hypre(const Decomposition& d, const Assembler& assembler,
                                   const DiffusionProblem& p, const SolveRegion& region,
                                   const DiffusionOptions& opt, Report& report) {
    const MPI_Comm comm = d.comm();
    LinearSolveOutput out;
    out.box = d.local().intersect(region.box);
    const Box& box = out.box;
    const size_t ncell = static_cast<size_t>(box.cells());
    const size_t nrhs = p.Q0.size();
    Int3 period{0, 0, 0};
    for (int a = 0; a < 3; ++a) period[a] = (p.periodic[a] && p.n[a] > 1) ? p.n[a] : 0;

    // 1. Grid, stencil, matrix, vectors (collective), rows from the Assembler.
    double t0 = wall_time();
    std::optional<ScopedTimer> timer(std::in_place, report, "assemble");
    hypre::Grid grid(comm, box, period);
    hypre::SymmetricStencil7 stencil;
    hypre::Matrix A(comm, grid, stencil);
    std::vector<std::vector<double>> b_values(nrhs, std::vector<double>(ncell));
    {
        std::vector<double> values(ncell * hypre::SymmetricStencil7::kEntries), b_cell(nrhs);
        size_t n = 0;
        for_each_cell(box, [&](int i, int j, int k) {
            const CellRow row = assembler.row(i, j, k, b_cell);
            for (size_t r = 0; r < nrhs; ++r) b_values[r][n] = b_cell[r];
            // Couplings to cells outside the grid are zero by construction: a full neighbour
            // is always inside the region, and the row of an empty cell has none.
            double* v = &values[n++ * hypre::SymmetricStencil7::kEntries];
            v[0] = row.diag;
            v[1] = -row.coupling[kXm];
            v[2] = -row.coupling[kYm];
            v[3] = -row.coupling[kZm];
        });
        A.set_box_values(box, values);
    }
    A.assemble();
    std::vector<double> b_norm(nrhs);
    for (size_t r = 0; r < nrhs; ++r) b_norm[r] = hypre::global_norm(b_values[r], comm);
    hypre::Vector b(comm, grid), x(comm, grid), res(comm, grid);
    b.set_box_values(box, b_values[0]);
    b.assemble();
    x.assemble();
    timer.reset();
    const double assemble_s = wall_time() - t0;

    // 2. Setup once for all right-hand sides.
    t0 = wall_time();
    hypre::Solver solver(comm, opt.solver, period[0] + period[1] + period[2] > 0);
    // hypre sizes its residual logs by the iteration limit at setup: set the largest one now.
    solver.set_max_iterations(opt.max_iterations);
    solver.set_tolerance(opt.tolerance);
    timer.emplace(report, "setup");
    solver.setup(A, b, x);
    timer.reset();
    const double setup_s = wall_time() - t0;

    // 3. Solve each rhs; restart from the current x while the TRUE residual is above tol.
    out.x.resize(nrhs);
    out.stats.resize(nrhs);
    for (size_t r = 0; r < nrhs; ++r) {
        SolveStats& st = out.stats[r];
        st.assemble_seconds = r == 0 ? assemble_s : 0.0;
        st.setup_seconds = r == 0 ? setup_s : 0.0;
        if (b_norm[r] == 0.0) {  // no source: U = 0
            out.x[r].assign(ncell, 0.0);
            continue;
        }
        t0 = wall_time();
        timer.emplace(report, "solve");
        if (r > 0) {
            b.set_box_values(box, b_values[r]);
            b.assemble();
        }
        std::vector<double> zero(ncell, 0.0);
        x.set_box_values(box, zero);
        x.assemble();
        const hypre::TrueResidualSolve sol = hypre::solve_to_true_residual(
            comm, solver, A, b, x, b_values[r], b_norm[r], box, res, opt.tolerance, opt.max_iterations);
        st.iterations = sol.iterations;
        st.restarts = sol.restarts;
        st.reported_residual = sol.reported_residual;
        st.true_residual = sol.true_residual;
        const auto& rounds = sol.rounds;
        log::debug("diffusion: rhs {}: {} {} iterations, relative residual {:.3e} (true {:.3e}), {} restarts", r,
                   sol.iterations, opt.solver, sol.reported_residual, sol.true_residual, sol.restarts);
        timer.reset();
        st.solve_seconds = wall_time() - t0;
        if (!sol.converged) {
            const std::string why =
                !std::isfinite(st.true_residual) ? "the residual is not finite"
                : sol.iterations >= opt.max_iterations
                    ? fmt::format("the limit of {} iterations was reached", opt.max_iterations)
                            : fmt::format("{} restarts from the last iterate did not bring the true residual down",
                                          rounds.size() - 1);
            // Residual history from zero at 1, 2, 4, ... iterations (true residuals).
            std::vector<std::pair<int, double>> history;
            solver.set_tolerance(0.0);
            for (int its = 1;; its = std::min(2 * its, opt.max_iterations)) {
                x.set_box_values(box, zero);
                x.assemble();
                solver.set_max_iterations(its);
                solver.solve(A, b, x);
                history.emplace_back(its, hypre::true_relative_residual(comm, A, x, b_values[r],
                                                                        b_norm[r], box, res));
                if (its >= opt.max_iterations) break;
            }
            throw Error(fmt::format(
                "diffusion: {} did not reach the relative residual {:.1e}: {} ({} iterations, "
                "true residual {:.3e}; true residual at the end of each round (the solver restarts "
                "from its last iterate while the recursive residual says done and the true one does "
                "not), iteration: {}); history from zero, iteration: true residual: {}",
                opt.solver, opt.tolerance, why, st.iterations, st.true_residual,
                format_history(rounds), format_history(history)));
        }
        x.get_box_values(box, out.x[r]);
    }
    return out;
}

}  // namespace nimbus::diffusion
