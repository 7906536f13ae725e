// PETSc back end of the diffusion model (linear_solve.h): a cross-check of the hypre path
// through an independent stack. DMDA over the whole domain with the decomposition's slab
// ownership, AIJ matrix (or what -diffusion_dm_mat_type selects), KSP CG with PCHYPRE
// BoomerAMG, stopping on the unpreconditioned 2-norm ||r|| <= tol ||b||. PETSc options with
// the prefix "diffusion_" override these choices, from model.diffusion.petsc_options (a private
// options database) or else PETSc's global options (PETSC_OPTIONS). Geometric multigrid:
// "-diffusion_pc_type mg -diffusion_pc_mg_levels L -diffusion_pc_mg_galerkin both" coarsens
// the DMDA attached to the KSP, which PETSc allows only when n - 1 is divisible by 2^(L-1)
// along every axis (e.g. 49 cells, L = 3); otherwise KSPSetUp fails with PETSc's message.
//
// Errors are one Error on every rank, with PETSc's message and without its traceback
// (petsc_support.h). model.diffusion.petsc_options is read twice: by check_petsc, before the
// light pass, into the DMDA and a KSP without a matrix (what they reject names the option); and
// by the solve, where an option that no object has read after the first KSPSolve is an error.
#include <petscdmda.h>
#include <petscksp.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "solvers/diffusion/linear_solve.h"
#include "solvers/diffusion/petsc_support.h"
#include "src/core/error.h"
#include "src/core/residual_history.h"

namespace nimbus::diffusion {
namespace {

constexpr const char* kKey = "model.diffusion.petsc_options";

void check(PetscErrorCode ierr, const std::string& what) { petsc::check(ierr, "diffusion (petsc)", what); }

// For the calls that read the options: the error also quotes model.diffusion.petsc_options.
void check_reading(PetscErrorCode ierr, const char* what, const DiffusionOptions& opt) {
    if (ierr == 0) return;
    check(ierr, opt.petsc_options.empty() ? std::string(what)
                                          : fmt::format("{} ({} = '{}')", what, kKey, opt.petsc_options));
}

void ensure_petsc(MPI_Comm comm) { petsc::ensure_initialized(comm); }

// The DMDA's owning handle (the others: petsc_support.h), destroyed in reverse order of declaration.
struct DMHandle {
    DM dm = nullptr;
    ~DMHandle() { if (dm) DMDestroy(&dm); }
};
using petsc::KSPHandle;
using petsc::MatHandle;
using petsc::OptionsHandle;
using petsc::VecHandle;

// model.diffusion.petsc_options as a private options database; none when empty (PETSc's global
// options then apply).
void create_options(const DiffusionOptions& opt, OptionsHandle& options) {
    if (opt.petsc_options.empty()) return;
    check(PetscOptionsCreate(&options.o), "PetscOptionsCreate");
    check(PetscOptionsInsertString(options.o, opt.petsc_options.c_str()), "PetscOptionsInsertString (petsc_options)");
}

// The DMDA over n cells with d's slab ownership (lz: layers per rank), set up after reading
// `options` (null: the global database) under the prefix "diffusion_". Collective.
void create_dmda(const Decomposition& d, const Int3& n, const std::array<bool, 3>& periodic, PetscOptions options,
                 const DiffusionOptions& opt, DMHandle& da) {
    const std::int64_t cells = static_cast<std::int64_t>(n[0]) * n[1] * n[2];  // the same on every rank
    check_collective(d.comm(), cells <= PETSC_MAX_INT,
                     fmt::format("diffusion: petsc: the grid has {} cells, more than this PETSc build's integers hold "
                                 "({}): use solver = \"pfmg-pcg\" (the solve region only), a coarser grid, or a PETSc "
                                 "configured with --with-64-bit-indices",
                                 cells, static_cast<std::int64_t>(PETSC_MAX_INT)));
    std::vector<PetscInt> lz(static_cast<size_t>(d.size()));
    for (int r = 0; r < d.size(); ++r) lz[static_cast<size_t>(r)] = d.box_of(r).size(2);
    DMBoundaryType bt[3];
    for (int a = 0; a < 3; ++a)
        bt[a] = (periodic[static_cast<size_t>(a)] && n[static_cast<size_t>(a)] > 1) ? DM_BOUNDARY_PERIODIC
                                                                                    : DM_BOUNDARY_NONE;
    check(DMDACreate3d(d.comm(), bt[0], bt[1], bt[2], DMDA_STENCIL_STAR, n[0], n[1], n[2], 1, 1, d.size(), 1, 1,
                       nullptr, nullptr, lz.data(), &da.dm),
          "DMDACreate3d");
    if (options) check(PetscObjectSetOptions(reinterpret_cast<PetscObject>(da.dm), options), "PetscObjectSetOptions");
    check(DMSetOptionsPrefix(da.dm, "diffusion_"), "DMSetOptionsPrefix");
    check_reading(DMSetFromOptions(da.dm), "DMSetFromOptions", opt);
    check_reading(DMSetUp(da.dm), "DMSetUp", opt);
}

// The KSP as the solve uses it, on operator A (null: none yet, for check_petsc) with the DMDA
// riding along, configured and then reading `options` (null: the global database) under the
// prefix "diffusion_". Not set up. Collective.
void create_ksp(MPI_Comm comm, Mat A, DM da, PetscOptions options, const DiffusionOptions& opt, KSPHandle& ksp) {
    check(KSPCreate(comm, &ksp.ksp), "KSPCreate");
    if (options) check(PetscObjectSetOptions(reinterpret_cast<PetscObject>(ksp.ksp), options), "PetscObjectSetOptions");
    check(KSPSetOptionsPrefix(ksp.ksp, "diffusion_"), "KSPSetOptionsPrefix");
    if (A) check(KSPSetOperators(ksp.ksp, A, A), "KSPSetOperators");
    // The DMDA rides along (inactive: the operator and right-hand sides are ours) so that
    // geometric preconditioners can coarsen it, e.g. -diffusion_pc_type mg with levels.
    check(KSPSetDM(ksp.ksp, da), "KSPSetDM");
    check(KSPSetDMActive(ksp.ksp, PETSC_FALSE), "KSPSetDMActive");
    check(KSPSetType(ksp.ksp, KSPCG), "KSPSetType");
    PC pc;
    check(KSPGetPC(ksp.ksp, &pc), "KSPGetPC");
    check(PCSetType(pc, PCHYPRE), "PCSetType");
    check(PCHYPRESetType(pc, "boomeramg"), "PCHYPRESetType");
    check(KSPSetNormType(ksp.ksp, KSP_NORM_UNPRECONDITIONED), "KSPSetNormType");
    check(KSPSetTolerances(ksp.ksp, opt.tolerance, 0.0, PETSC_DEFAULT, opt.max_iterations), "KSPSetTolerances");
    check(KSPSetResidualHistory(ksp.ksp, nullptr, PETSC_DECIDE, PETSC_TRUE), "KSPSetResidualHistory");
    check_reading(KSPSetFromOptions(ksp.ksp), "KSPSetFromOptions", opt);
}

// Empty if every rank's PETSc accepts `options` when the DMDA on d's grid and a KSP without a
// matrix read them; else PETSc's message (the lowest failing rank's, on every rank). Collective.
std::string rejection(const Decomposition& d, PetscOptions options, const DiffusionOptions& opt) {
    const Box& g = d.global();
    try {
        run_collective(d.comm(), [&] {
            try {
                DMHandle da;
                create_dmda(d, g.shape(), {d.periodic(0), d.periodic(1), d.periodic(2)}, options, opt, da);
                KSPHandle ksp;
                create_ksp(d.comm(), nullptr, da.dm, options, opt, ksp);
            } catch (const petsc::Failure& f) {
                throw Error(f.petsc_message());
            }
        });
    } catch (const Error& e) {
        return e.what();
    }
    return {};
}

// The options no object has read after the first KSPSolve were ignored: an Error naming them.
// PETSc 3.18 gives the inner solvers it creates (PCMG's levels, PCBJACOBI's and PCASM's blocks)
// the global database, not the private one: their options ("-diffusion_mg_levels_ksp_type",
// "-diffusion_sub_pc_type") are read from PETSc's global options (PETSC_OPTIONS) only. Collective.
void check_all_read(MPI_Comm comm, PetscOptions options) {
    std::string unread;
    bool inner = false;
    for (const petsc::Option& o : petsc::unread_options(options)) {
        unread += fmt::format("{}'{}'", unread.empty() ? "" : ", ", o.text());
        for (const char* part : {"_mg_levels_", "_mg_coarse_", "_sub_"})
            inner = inner || o.name.find(part) != std::string::npos;
    }
    check_collective(comm, unread.empty(),
                     fmt::format("{}: PETSc did not use {} (misspelled, or no object of this solve reads it{})",
                                 kKey, unread,
                                 inner ? "; the inner solvers of PCMG, PCBJACOBI and PCASM read only PETSc's "
                                         "global options, PETSC_OPTIONS"
                                       : ""));
}

const char* const kNeedsSlabs =
    "model.diffusion.solver = \"petsc\" needs slabs along z (grid.process_grid = [1, 1, P]); the hypre solvers "
    "(pfmg-pcg, the default) take any process grid";

}  // namespace

void check_petsc_layout(const Decomposition& d) {
    if (!d.is_slab_z()) throw Error(kNeedsSlabs);
}

void check_petsc(const Decomposition& d, const DiffusionOptions& opt) {
    check_petsc_layout(d);
    if (opt.petsc_options.empty()) return;
    const petsc::OptionsText text = petsc::read_options_text(opt.petsc_options);
    if (!text.stray.empty())
        throw Error(fmt::format("{}: PETSc would ignore '{}' in '{}' (an option is a name starting with - "
                                "and at most one value)",
                                kKey, text.stray.front(), opt.petsc_options));
    // The stopping test is the model's (the TRUE relative residual, checked after the solve):
    // options that would change it would only turn into a "did not reach" error.
    for (const petsc::Option& o : text.options) {
        const bool stop_test = o.name == "-diffusion_ksp_rtol" || o.name == "-diffusion_ksp_atol" ||
                               o.name == "-diffusion_ksp_norm_type" ||
                               o.name == "-diffusion_ksp_converged_use_initial_residual_norm" ||
                               o.name == "-diffusion_ksp_converged_use_min_initial_residual_norm";
        const char* owner = stop_test ? "model.diffusion.tolerance (the relative residual every solve reaches)"
                            : o.name == "-diffusion_ksp_max_it" ? "model.diffusion.max_iterations"
                                                                : nullptr;
        if (owner) throw Error(fmt::format("{}: '{}' is set by {}; leave it out of petsc_options", kKey, o.name, owner));
    }
    const MPI_Comm comm = d.comm();
    ensure_petsc(comm);
    const petsc::QuietErrors quiet;
    OptionsHandle all;
    create_options(opt, all);
    for (const petsc::Option& o : petsc::unread_options(all.o))
        if (o.name.rfind("-diffusion_", 0) != 0)
            throw Error(fmt::format("{}: '{}' lacks the prefix of the solver's options, -diffusion_ (e.g. "
                                    "-diffusion_pc_type)",
                                    kKey, o.name));
    const std::string message = rejection(d, all.o, opt);
    if (message.empty()) return;
    // Name the option: the first whose addition to the ones before it PETSc rejects.
    for (size_t k = 1; k <= text.options.size(); ++k) {
        OptionsHandle first;
        check(PetscOptionsCreate(&first.o), "PetscOptionsCreate");
        for (size_t i = 0; i < k; ++i) {
            const petsc::Option& o = text.options[i];
            check(PetscOptionsSetValue(first.o, o.name.c_str(), o.value.empty() ? nullptr : o.value.c_str()),
                  "PetscOptionsSetValue");
        }
        const std::string m = rejection(d, first.o, opt);
        if (!m.empty()) throw Error(fmt::format("{}: PETSc rejected '{}': {}", kKey, text.options[k - 1].text(), m));
    }
    throw Error(fmt::format("{}: PETSc rejected '{}': {}", kKey, opt.petsc_options, message));
}

LinearSolveOutput solve_with_petsc(const Decomposition& d, const Assembler& assembler,
                                   const DiffusionProblem& p, const SolveRegion& region,
                                   const DiffusionOptions& opt, Report& report) {
    const MPI_Comm comm = d.comm();
    if (!d.is_slab_z()) throw Error(kNeedsSlabs);
    ensure_petsc(comm);
    const petsc::QuietErrors quiet;
    LinearSolveOutput out;
    out.box = d.local().intersect(region.box);
    const Box& own = d.local();
    const size_t nrhs = p.Q0.size();

    double t0 = wall_time();
    std::optional<ScopedTimer> timer(std::in_place, report, "assemble");
    // model.diffusion.petsc_options: a private options database for this solve's DM and KSP
    // (declared first, so destroyed after them).
    OptionsHandle options;
    create_options(opt, options);
    DMHandle da;
    create_dmda(d, p.n, p.periodic, options.o, opt, da);
    PetscInt xs, ys, zs, xm, ym, zm;
    check(DMDAGetCorners(da.dm, &xs, &ys, &zs, &xm, &ym, &zm), "DMDAGetCorners");
    check_collective(comm, xs == own.lo[0] && ys == own.lo[1] && zs == own.lo[2] && xm == own.size(0) &&
                               ym == own.size(1) && zm == own.size(2),
                     "diffusion (petsc): DMDA ownership differs from the decomposition");

    MatHandle A;
    check_reading(DMCreateMatrix(da.dm, &A.m), "DMCreateMatrix", opt);
    run_collective(comm, [&] {  // local: a failure here must not leave the other ranks in MatAssemblyBegin
        const int offs[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
        for_each_cell(own, [&](int i, int j, int k) {
            MatStencil row{k, j, i, 0}, cols[7];
            PetscScalar vals[7];
            int n = 0;
            const bool in_region = region.box.contains(i, j, k);
            const CellRow cr = in_region ? assembler.row(i, j, k) : CellRow{};
            cols[n] = row;
            vals[n++] = cr.diag;
            for (int e = 0; e < 6; ++e) {
                if (cr.coupling[static_cast<size_t>(e)] == 0.0) continue;
                cols[n] = MatStencil{k + offs[e][2], j + offs[e][1], i + offs[e][0], 0};
                vals[n++] = -cr.coupling[static_cast<size_t>(e)];
            }
            check(MatSetValuesStencil(A.m, 1, &row, n, cols, vals, ADD_VALUES), "MatSetValuesStencil");
        });
    });
    check(MatAssemblyBegin(A.m, MAT_FINAL_ASSEMBLY), "MatAssemblyBegin");
    check(MatAssemblyEnd(A.m, MAT_FINAL_ASSEMBLY), "MatAssemblyEnd");
    VecHandle b, x, res;
    check(DMCreateGlobalVector(da.dm, &b.v), "DMCreateGlobalVector");
    check(VecDuplicate(b.v, &x.v), "VecDuplicate");
    check(VecDuplicate(b.v, &res.v), "VecDuplicate");
    timer.reset();
    const double assemble_s = wall_time() - t0;

    t0 = wall_time();
    timer.emplace(report, "setup");
    KSPHandle ksp;
    create_ksp(comm, A.m, da.dm, options.o, opt, ksp);
    check_reading(KSPSetUp(ksp.ksp), "KSPSetUp", opt);
    timer.reset();
    const double setup_s = wall_time() - t0;

    out.x.resize(nrhs);
    out.stats.resize(nrhs);
    bool options_checked = !options.o;
    for (size_t r = 0; r < nrhs; ++r) {
        SolveStats& st = out.stats[r];
        st.assemble_seconds = r == 0 ? assemble_s : 0.0;
        st.setup_seconds = r == 0 ? setup_s : 0.0;
        t0 = wall_time();
        timer.emplace(report, "solve");
        run_collective(comm, [&] {
            PetscScalar*** bv;
            check(DMDAVecGetArray(da.dm, b.v, &bv), "DMDAVecGetArray");
            for_each_cell(own, [&](int i, int j, int k) {
                bv[k][j][i] = region.box.contains(i, j, k) ? assembler.rhs(static_cast<int>(r), i, j, k) : 0.0;
            });
            check(DMDAVecRestoreArray(da.dm, b.v, &bv), "DMDAVecRestoreArray");
        });
        PetscReal b_norm = 0, r_norm = 0;
        check(VecNorm(b.v, NORM_2, &b_norm), "VecNorm");
        check(VecSet(x.v, 0.0), "VecSet");
        if (b_norm > 0) {
            check_reading(KSPSolve(ksp.ksp, b.v, x.v), "KSPSolve", opt);
            if (!options_checked) {
                check_all_read(comm, options.o);
                options_checked = true;
            }
            PetscInt its = 0;
            check(KSPGetIterationNumber(ksp.ksp, &its), "KSPGetIterationNumber");
            PetscReal rn = 0;
            check(KSPGetResidualNorm(ksp.ksp, &rn), "KSPGetResidualNorm");
            st.iterations = static_cast<int>(its);
            st.reported_residual = rn / b_norm;
            check(MatMult(A.m, x.v, res.v), "MatMult");
            check(VecAYPX(res.v, -1.0, b.v), "VecAYPX");
            check(VecNorm(res.v, NORM_2, &r_norm), "VecNorm");
            st.true_residual = r_norm / b_norm;
        }
        timer.reset();
        st.solve_seconds = wall_time() - t0;
        if (!(st.true_residual <= opt.tolerance)) {
            const PetscReal* hist = nullptr;
            PetscInt nh = 0;
            KSPGetResidualHistory(ksp.ksp, &hist, &nh);
            std::vector<std::pair<int, double>> history;
            for (PetscInt h = 0; h < nh; ++h) history.emplace_back(static_cast<int>(h), hist[h] / b_norm);
            KSPType type = nullptr;
            KSPGetType(ksp.ksp, &type);
            KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
            KSPGetConvergedReason(ksp.ksp, &reason);
            // CONVERGED_ITS: a fixed number of iterations without a residual test (preonly, or
            // richardson without norms): "converged" only in PETSc's sense.
            const std::string why = reason == KSP_CONVERGED_ITS
                                        ? "CONVERGED_ITS (a fixed number of iterations, no residual test)"
                                        : KSPConvergedReasons[reason];
            throw Error(fmt::format(
                "diffusion: petsc {} did not reach the relative residual {:.1e}: it stopped with {} after {} "
                "iterations (true residual {:.3e}); {}",
                type ? type : "KSP", opt.tolerance, why, st.iterations, st.true_residual,
                history.empty() ? std::string("no residual history (this KSP computed no residual norms)")
                                : "history, iteration: relative residual: " + format_history(history)));
        }
        run_collective(comm, [&] {
            const PetscScalar*** xv;
            check(DMDAVecGetArrayRead(da.dm, x.v, &xv), "DMDAVecGetArrayRead");
            out.x[r].clear();
            out.x[r].reserve(static_cast<size_t>(out.box.cells()));
            for_each_cell(out.box, [&](int i, int j, int k) { out.x[r].push_back(xv[k][j][i]); });
            check(DMDAVecRestoreArrayRead(da.dm, x.v, &xv), "DMDAVecRestoreArrayRead");
        });
    }
    return out;
}

}  // namespace nimbus::diffusion
