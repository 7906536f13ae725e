#include "solvers/diffusion/solve_diffusion.h"

#include <algorithm>

#include "solvers/diffusion/assemble.h"
#include "solvers/diffusion/linear_solve.h"
#include "solvers/diffusion/solve_region.h"
#include "src/core/halo.h"

namespace nimbus::diffusion {

DiffusionResult solve_diffusion(const Decomposition& d, const DiffusionProblem& p,
                                const DiffusionOptions& opt, Report& report) {
    const size_t nrhs = p.Q0.size();
    DiffusionResult res;
    res.region = find_solve_region(d, p, opt.margin);
    for (size_t r = 0; r < nrhs; ++r) {
        res.U.emplace_back(d.local(), 1, 1, 0.0);
        res.flux.emplace_back(d.local(), 1, 3, 0.0);
    }
    res.stats.resize(nrhs);

    auto& rec = report.values()["diffusion"];
    rec["solver"] = opt.solver;
    rec["tolerance"] = opt.tolerance;
    rec["region"] = {{"lo", res.region.box.lo}, {"hi", res.region.box.hi},
                     {"cells", res.region.cells()}};
    if (res.region.box.empty()) return res;  // nothing scatters

    // Cap of the transport mean free path (diffusion_kernel.h): the option, or the region size.
    double ell = opt.max_transport_length;
    if (ell <= 0.0) ell = default_transport_length(res.region, p);
    rec["kappa_tr_floor"] = 1.0 / ell;
    const Assembler assembler(p, 1.0 / ell);
    LinearSolveOutput lin = opt.solver == "petsc"
                                ? solve_with_petsc(d, assembler, p, res.region, opt, report)
                                : solve_with_hypre(d, assembler, p, res.region, opt, report);
    for (size_t r = 0; r < nrhs; ++r) {
        size_t n = 0;
        for_each_cell(lin.box, [&](int i, int j, int k) {
            const double u = lin.x[r][n++];
            res.U[r](i, j, k) = assembler.full(i, j, k) ? u : 0.0;
        });
        exchange_halo(res.U[r], d);
        for_each_cell(d.local(), [&](int i, int j, int k) {
            const Vec3 F = assembler.flux(static_cast<int>(r), res.U[r], i, j, k);
            for (int c = 0; c < 3; ++c) res.flux[r](i, j, k, c) = F[c];
        });
        exchange_halo(res.flux[r], d);
        res.stats[r] = lin.stats[r];
        SolveStats& st = res.stats[r];
        std::int64_t neg[2] = {0, 0}, gneg[2];
        double umin[2] = {0.0, 0.0}, gumin[2];
        for_each_cell(d.local(), [&](int i, int j, int k) {
            double& u = res.U[r](i, j, k);
            if (u >= 0.0) return;
            const int c = assembler.has_marshak_face(i, j, k) ? 0 : 1;
            ++neg[c];
            umin[c] = std::min(umin[c], u);
            if (opt.clamp_negative) u = 0.0;
        });
        MPI_Allreduce(neg, gneg, 2, MPI_INT64_T, MPI_SUM, d.comm());
        MPI_Allreduce(umin, gumin, 2, MPI_DOUBLE, MPI_MIN, d.comm());
        st.min_U = std::min(gumin[0], gumin[1]);
        st.min_U_interior = gumin[1];
        st.negative_boundary_cells = gneg[0];
        st.negative_interior_cells = gneg[1];
        if (opt.clamp_negative && gneg[0] + gneg[1] > 0) exchange_halo(res.U[r], d);
        rec["systems"].push_back({{"iterations", st.iterations},
                                  {"restarts", st.restarts},
                                  {"reported_residual", st.reported_residual},
                                  {"true_residual", st.true_residual},
                                  {"assemble_seconds", st.assemble_seconds},
                                  {"setup_seconds", st.setup_seconds},
                                  {"solve_seconds", st.solve_seconds},
                                  {"negative_boundary_cells", st.negative_boundary_cells},
                                  {"negative_interior_cells", st.negative_interior_cells},
                                  {"min_U", st.min_U},
                                  {"min_U_interior", st.min_U_interior}});
    }
    return res;
}

}  // namespace nimbus::diffusion
