#include "solvers/lpm/solve_band.h"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "solvers/lpm/map_sweep.h"
#include "solvers/lpm/tail.h"
#include "src/core/log.h"
#include "src/core/halo.h"
#include "src/physics/lights.h"

namespace nimbus::lpm {
namespace {

double global_sum(double v, MPI_Comm c) {
    MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, MPI_SUM, c);
    return v;
}
double global_max(double v, MPI_Comm c) {
    MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, MPI_MAX, c);
    return v;
}

// U^m += sign κ a (φ + 3 g F·ω̄^m)/(4π) on the owned cells: the HG scattering of the P1
// radiance (φ + 3 F·ω)/(4π) of correction t, averaged over coarse bin m (mean direction ω̄^m);
// g = 0 scatters its isotropic part alone.
void add_p1_scattering(Field<double>& U, double sign, const DiffusionTail& t, const Field<double>& kappa,
                       double albedo, double g, const std::vector<Vec3>& mean) {
    const int nm = U.ncomp();
    const double c = sign * albedo / (4.0 * std::numbers::pi);
    for_each_cell(U.owned(), [&](int i, int j, int k) {
        const double s = c * kappa(i, j, k);
        if (s == 0.0) return;
        const double phi = t.fluence(i, j, k);
        const Vec3 F{t.flux(i, j, k, 0), t.flux(i, j, k, 1), t.flux(i, j, k, 2)};
        double* u = &U(i, j, k);
        for (int m = 0; m < nm; ++m) u[m] += s * (phi + 3.0 * g * dot(F, mean[static_cast<size_t>(m)]));
    });
}

}  // namespace

BandResult solve_sources(const Decomposition& d, const Medium& m, const LightTransport& light, const BandOptics& bo,
                         const std::vector<double>& strength, const LpmOptions& opt, const Angular& ang,
                         Progress* progress, double progress_offset, Report* report,
                         const std::vector<VolumeSource>& sources) {
    const size_t nl = light.lights.size();
    const Box& own = d.local();
    const int nm = ang.coarse_bins();
    const double V = m.grid.cell_volume();

    // Extinction on the owned box and its ghosts (the maps read the neighbours' ghost planes).
    Field<double> kappa(own, 1, 1, 0.0);
    for (size_t i = 0; i < kappa.size(); ++i) kappa.data()[i] = m.rho.data()[i] * bo.sigma_t;

    const std::vector<double>& P = ang.form_factors(bo.g);
    std::vector<double> deposit(P.size());
    for (int n = 0; n < ang.map_bins(); ++n)
        for (int c = 0; c < nm; ++c)
            deposit[static_cast<size_t>(n * nm + c)] = P[static_cast<size_t>(n * nm + c)] / ang.coarse_solid_angle(c);

    // First-scatter source, split over the coarse bins by the exact beam factors.
    Field<double> U(own, 1, nm, 0.0);
    double source = 0.0;
    std::vector<bool> lit(nl);
    for (size_t l = 0; l < nl; ++l) lit[l] = strength[l] != 0.0;
    FirstScatterBound first_scatter;
    {  // the means (and the copy they keep) only for this pass
        const FirstScatterMeans means(light, d, m.rho, bo.sigma_t, m.grid.h, lit);
        first_scatter = means.bound();
        for (size_t l = 0; l < light.lights.size(); ++l) {
            const DirectionalLight& dl = light.lights[l];
            const double E0 = strength[l];
            if (E0 == 0.0) continue;
            const std::vector<double>& bf = ang.beam_factors(bo.g, dl.w);
            for_each_cell(own, [&](int i, int j, int k) {
                // The cell's mean of T (the deposit integrates the source over the cell), where the
                // cell scatters.
                const double ks = kappa(i, j, k) * bo.albedo;
                if (ks == 0.0) return;
                const double q = ks * E0 * means(static_cast<int>(l), i, j, k);
                if (q == 0.0) return;
                source += q * V;
                double* u = &U(i, j, k);
                for (int c = 0; c < nm; ++c) u[c] += q * bf[static_cast<size_t>(c)] / ang.coarse_solid_angle(c);
            });
        }
    }
    // Volume emission: isotropic, power/4π in every bin (W/(m³ sr)).
    if (!sources.empty())
        for_each_cell(own, [&](int i, int j, int k) {
            const double power =
                emitted_power_at(sources, m.rho, [&](size_t t) { return strength[nl + t]; }, i, j, k, {i, j, k});
            if (power == 0.0) return;
            source += power * V;
            double* u = &U(i, j, k);
            for (int c = 0; c < nm; ++c) u[c] += power / (4.0 * std::numbers::pi);
        });
    double u_max0 = 0.0;
    for_each_cell(own, [&](int i, int j, int k) {
        for (int c = 0; c < nm; ++c) u_max0 = std::max(u_max0, U(i, j, k, c));
    });
    u_max0 = global_max(u_max0, d.comm());

    BandResult r;
    r.first_scatter = first_scatter;
    r.source = global_sum(source, d.comm());
    Field<double> fluence(own, 1, 1, 0.0);
    Field<double> flux;
    if (opt.solution_bins == 4) flux = Field<double>(own, 1, 3, 0.0);

    MapInputs in;
    in.angular = &ang;
    in.refinement = opt.refinement;
    in.h = m.grid.h;
    in.kappa = &kappa;
    in.albedo = bo.albedo;
    in.deposit = &deposit;
    in.flux = opt.solution_bins == 4;
    MapAccumulators acc;
    acc.U = &U;
    acc.fluence = &fluence;
    acc.flux = in.flux ? &flux : nullptr;

    const bool geometric = opt.tail == "geometric";
    // Diffusion synthetic acceleration (tail "dsa", solve_band.h): the P1 correction of the last
    // round, fed back into U as its scattering S(f) (with the current for the first correction,
    // isotropic after: g_f).
    const bool dsa = opt.tail == "dsa";
    const std::vector<Vec3> mean = dsa ? coarse_mean_directions(ang) : std::vector<Vec3>{};
    DiffusionTail correction;
    double correction_g = 0.0;
    bool corrected = false;
    Report scratch_report;
    Report& solver_report = report ? *report : scratch_report;
    Field<double> previous;  // fluence before the last iteration (geometric tail)
    double previous_remaining = r.source;
    for (int it = 0; it < opt.iterations && u_max0 > 0.0; ++it) {
        if (geometric) previous = fluence;
        if (it > 0) previous_remaining = r.remaining_history.back();
        for (int f : kMapOrder) {
            const double t0 = MPI_Wtime();
            sweep_map(d, f, in, acc);
            r.sweep_seconds.push_back(MPI_Wtime() - t0);
            if (progress) progress->update(progress_offset + static_cast<double>(r.sweep_seconds.size()));
        }
        ++r.iterations;
        if (dsa && r.iterations < opt.iterations) {
            // The round propagated all of U and left in it S(δ_n), the scattering of its increment;
            // minus S(f_{n-1}) that is the scattering of the iterate's change δ_n - f_{n-1}, the
            // error's source, whose P1 solution is the new correction f_n; U += S(f_n) makes the
            // next round propagate it.
            if (corrected) add_p1_scattering(U, -1.0, correction, kappa, bo.albedo, correction_g, mean);
            correction_g = corrected ? 0.0 : bo.g;
            correction = diffusion_tail(d, m, bo, U, kappa, ang, solver_report, !corrected, false);
            add_p1_scattering(U, 1.0, correction, kappa, bo.albedo, correction_g, mean);
            corrected = true;
            ++r.dsa_corrections;
            r.dsa_solver_iterations += correction.solver_iterations;
        }
        double u_max = 0.0, left = 0.0;
        for_each_cell(own, [&](int i, int j, int k) {
            for (int c = 0; c < nm; ++c) {
                u_max = std::max(u_max, std::abs(U(i, j, k, c)));  // DSA leaves U of either sign
                left += V * ang.coarse_solid_angle(c) * U(i, j, k, c);
            }
        });
        r.max_U.push_back(global_max(u_max, d.comm()) / u_max0);
        r.remaining_history.push_back(global_sum(left, d.comm()));
        log::debug("lpm: iteration {}: max U / initial {:.3e}, unpropagated power {:.4g} W", r.iterations,
                   r.max_U.back(), r.remaining_history.back());
        // DSA diverges where its P1 correction is not consistent with the maps: on optically thick
        // cells at high albedo it over-corrects and max |U| grows from round to round (a box of
        // 20 optical depths per cell at albedo 0.999: 270, 2887, 3923 times the first-scatter
        // maximum, fluence_diffuse 1145 where Monte Carlo gives 2.7, negative energies). Healthy
        // solves shrink it every round after the first correction (all study scenes). The band is
        // then solved again with the plain P1 tail, which these cells do not destabilize, and
        // the result says so (the caller warns). max_U is a global max: every rank decides alike.
        if (dsa && r.max_U.size() >= 2 && r.max_U.back() > r.max_U[r.max_U.size() - 2]) {
            LpmOptions plain = opt;
            plain.tail = "diffusion";
            BandResult again = solve_sources(d, m, light, bo, strength, plain, ang, progress, progress_offset, report,
                                             sources);
            again.dsa_diverged_max_U = r.max_U;
            return again;
        }
        if (r.max_U.back() < opt.epsilon) break;
    }

    // After the last round (or a stop right after a correction) U less the last S(f) is the
    // error's source, whose P1 solution is the tail below. Every S(f) added is so removed once,
    // and the energy balance closes as without DSA.
    if (corrected) add_p1_scattering(U, -1.0, correction, kappa, bo.albedo, correction_g, mean);
    double absorbed = 0.0, remaining = 0.0;
    for_each_cell(own, [&](int i, int j, int k) {
        absorbed += V * (1.0 - bo.albedo) * kappa(i, j, k) * fluence(i, j, k);
        for (int c = 0; c < nm; ++c) remaining += V * ang.coarse_solid_angle(c) * U(i, j, k, c);
    });
    r.absorbed = global_sum(absorbed, d.comm());
    r.remaining = global_sum(remaining, d.comm());
    for (int a = 0; a < 3; ++a)
        for (int side = 0; side < 2; ++side) {
            r.escaped_face[a][side] = global_sum(acc.escaped[a][side], d.comm());
            r.escaped += r.escaped_face[a][side];
        }
    r.truncated = global_sum(acc.truncated, d.comm());
    r.wait_seconds = acc.wait_seconds;

    // The light left in U (tail.h).
    if (geometric && r.iterations > 0) {
        r.tail_factor = geometric_tail_factor(r.remaining, previous_remaining);
        add_geometric_tail(fluence, previous, r.tail_factor);
        // The flux, when asked for, is left without the tail (its increment is not kept).
    } else if ((opt.tail == "diffusion" && r.remaining > 0.0) || (dsa && !r.max_U.empty() && r.max_U.back() > 0.0)) {
        // The plain tail's U is non-negative and its P1 fluence clamped at 0 (README); DSA's
        // source has either sign and is not.
        DiffusionTail t = diffusion_tail(d, m, bo, U, kappa, ang, solver_report, true, !dsa);
        r.tail_solver_iterations = t.solver_iterations;
        for_each_cell(own, [&](int i, int j, int k) {
            fluence(i, j, k) += t.fluence(i, j, k);
            if (in.flux)
                for (int c = 0; c < 3; ++c) flux(i, j, k, c) += t.flux(i, j, k, c);
        });
    }
    exchange_halo(fluence, d);
    r.fluence = std::move(fluence);
    if (in.flux) {
        exchange_halo(flux, d);
        r.flux = std::move(flux);
    }
    return r;
}

BandResult solve_band(const Decomposition& d, const Medium& m, const LightTransport& light, int band,
                      const LpmOptions& opt, const Angular& ang, Progress* progress, Report* report,
                      const std::vector<VolumeSource>& sources) {
    std::vector<double> strength;
    for (const DirectionalLight& l : light.lights) strength.push_back(band_value(l.E0, band));
    for (const VolumeSource& v : sources) strength.push_back(v.power[static_cast<size_t>(band)]);
    return solve_sources(d, m, light, m.bands[static_cast<size_t>(band)], strength, opt, ang, progress,
                         static_cast<double>(band * opt.iterations * 6), report, sources);
}

}  // namespace nimbus::lpm
