#include "solvers/dom/iteration.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>

#include "solvers/dom/dsa.h"
#include "solvers/dom/gmres.h"
#include "src/core/log.h"
#include "src/physics/angular_moments.h"

namespace nimbus::dom {
namespace {

// The isotropic DSA's own rate is about 0.22 per iteration (isotropic scattering, infinite
// medium, jobs/dsa_fourier.py); a slower change means an anisotropic mode the current's
// correction removes. Thin media converge faster (the smoke: 0.025, 0.016) and never pay for it.
constexpr double kCurrentFromRatio = 0.2;

}  // namespace

bool stalled(const std::vector<double>& history) {
    const size_t n = history.size(), w = static_cast<size_t>(kStallWindow);
    if (n < 2 * w) return false;
    const double before = *std::min_element(history.begin(), history.end() - static_cast<std::ptrdiff_t>(w));
    const double recent = *std::min_element(history.end() - static_cast<std::ptrdiff_t>(w), history.end());
    return recent > kStallGrowth * before;
}

bool blew_up(const std::vector<double>& norms) {
    if (norms.empty()) return false;
    if (!std::isfinite(norms.back())) return true;
    return norms.front() > 0.0 && norms.back() > kBlowUp * norms.front();
}

namespace {

// Whether every owned cell's fluence is finite, on all ranks (collective).
bool all_finite(const Field<double>& f, MPI_Comm comm) {
    int finite = 1;
    for_each_cell(f.owned(), [&](int i, int j, int k) {
        if (!std::isfinite(f(i, j, k))) finite = 0;
    });
    MPI_Allreduce(MPI_IN_PLACE, &finite, 1, MPI_INT, MPI_MIN, comm);
    return finite == 1;
}

}  // namespace

IterationResult iterate_band(const Decomposition& d, TransportSweeper& sweeper, const AngularSet& ang,
                             const BandProblem& p, const std::string& method, double tolerance,
                             int max_iterations, SweepOutput& out, Report& report,
                             const IterationMonitor& monitor) {
    if (method == "gmres" || method == "gmres-plain")
        return gmres_band(d, sweeper, ang, p, tolerance, max_iterations, out, report,
                          method == "gmres" ? GmresPreconditioner::dsa : GmresPreconditioner::none, monitor);
    const double t0 = MPI_Wtime();
    IterationResult res;
    const Box& own = d.local();
    std::unique_ptr<DiffusionSynthetic> dsa;
    if (method == "dsa") {
        ScopedTimer t(report, "dsa_setup");
        dsa = std::make_unique<DiffusionSynthetic>(d, p, sweeper.boundary().reflective, true);
    }
    const double y00 = 1.0 / std::sqrt(4.0 * std::acos(-1.0));
    const double y1 = first_moment_scale();
    // phi (the iterate) and s, the source moments, live on the source rows' cells, packed
    // (transport_sweep.h): elsewhere sigma_s is 0 and phi feeds no source.
    const SourceRows rows = source_rows(p);
    const size_t nm = static_cast<size_t>(ang.nmom);
    std::vector<double> phi(rows.cells() * nm, 0.0), s(rows.cells() * nm, 0.0);
    const std::vector<double> chi = moment_chi(p, ang);
    Field<double> fluence_old(own, 0, 1, 0.0), flux_old(own, 0, 3, 0.0);
    Field<double> mirror_source(own, 0, 1, 0.0);  // DSA's boundary source on high mirror faces
    bool correct_current = false;  // DSA's current correction, switched on below
    SweepSource src;
    src.kappa = &p.kappa;
    src.moments = s;
    src.amp = &p.amp;
    src.nl = p.nl;
    src.light_phase = p.light_phase;
    src.rows = &rows;
    // The sweeps cover the bounding box of the medium and its sources (TransportSweeper::region);
    // one last sweep of the whole domain gives the fields.
    const std::optional<Box> region = sweeper.region(p.kappa, rows);
    src.region = region ? &*region : nullptr;
    std::vector<double> norms;  // of the fluence, per iteration (blew_up)
    for (int it = 1; it <= max_iterations; ++it) {
        make_source_moments(p, chi, rows, phi.data(), s.data(), true);
        sweeper.sweep(src, out);
        if (dsa) {
            bool finite = true;
            {
                // Ranks arrive unevenly from the sweep: the check's reduction waits for them, which
                // stays out of the solve's timer. A diverged iterate must not reach DSA's hypre
                // solve (NaN there is hypre's own error print); without DSA, blew_up sees it.
                ScopedTimer w(report, "dsa_wait");
                finite = all_finite(out.fluence, d.comm());
            }
            if (!finite) {
                res.stalled = true;
                res.divergence = fmt::format("the fluence of iteration {} is not finite", it);
                break;
            }
            ScopedTimer t(report, "dsa_solve");
            mirror_source.fill(0.0);
            sweeper.for_each_lagged_mirror_change(
                [&](int i, int j, int k, double dJ) { mirror_source(i, j, k) += dJ / p.h; });
            res.dsa_linear_iterations +=
                dsa->correct(fluence_old, flux_old, out.fluence, out.flux, correct_current, &mirror_source);
            // The corrections (fields on own, 0 outside DSA's box) of the moments on the rows.
            const double* delta = dsa->last_correction().data();
            const double* current = dsa->last_current_correction().data();
            const bool first_moments = correct_current && ang.nmom >= 4;
            double* ph = out.phi.data();
            rows.for_each_cell([&](size_t c, size_t q) {
                ph[q * nm] += y00 * delta[c];
                if (!first_moments) return;
                for (int m = 1; m <= 3; ++m) {
                    const auto axis = static_cast<size_t>(first_moment_axis(m));
                    ph[q * nm + static_cast<size_t>(m)] += y1 * current[3 * c + axis];
                }
            });
        }
        double sums[2] = {0.0, 0.0};
        for_each_cell(own, [&](int i, int j, int k) {
            const double diff = out.fluence(i, j, k) - fluence_old(i, j, k);
            sums[0] += diff * diff;
            sums[1] += out.fluence(i, j, k) * out.fluence(i, j, k);
        });
        MPI_Allreduce(MPI_IN_PLACE, sums, 2, MPI_DOUBLE, MPI_SUM, d.comm());
        const double change = sums[1] > 0 ? std::sqrt(sums[0] / sums[1]) : 0.0;
        // DSA corrects the current (twice the cost of a step) once a slow mode shows: a change
        // falling by less than kCurrentFromRatio per iteration.
        if (!res.history.empty() && change > kCurrentFromRatio * res.history.back()) correct_current = true;
        res.history.push_back(change);
        res.iterations = it;
        norms.push_back(std::sqrt(sums[1]));
        notify(monitor, res.history);
        if (blew_up(norms)) {
            res.stalled = true;
            res.divergence = std::isfinite(norms.back())
                                 ? fmt::format("the fluence has grown to {:.1e} times its first iterate's",
                                               norms.back() / norms.front())
                                 : fmt::format("the fluence's norm at iteration {} is not finite (overflow)", it);
            break;
        }
        log::debug("dom: {} iteration {}: relative change {:.3e}{}", method, it, change,
                   dsa ? fmt::format(" (DSA: {} PFMG V-cycles so far)", res.dsa_linear_iterations) : "");
        std::swap(phi, out.phi);  // phi: the current iterate, feeds the next source
        fluence_old = out.fluence;
        flux_old = out.flux;
        if (change <= tolerance) {
            res.converged = true;
            break;
        }
        if (stalled(res.history)) {
            res.stalled = true;
            res.divergence = fmt::format("the relative change has stayed above {:g} times its lowest value for {} "
                                         "iterations", kStallGrowth, kStallWindow);
            break;
        }
    }
    if (region && res.converged) {  // phi: the converged iterate
        make_source_moments(p, chi, rows, phi.data(), s.data(), true);
        src.region = nullptr;
        sweeper.sweep(src, out);
    } else {
        std::swap(phi, out.phi);
    }
    res.seconds = MPI_Wtime() - t0;
    return res;
}

}  // namespace nimbus::dom
