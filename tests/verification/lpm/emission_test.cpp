// Volume emission ([[sources]]) in the light propagation maps: power/4π in every coarse bin of
// U (solve_band.h). A uniform source deep in a thick pure absorber: the fluence is power/κ
// (every direction's radiance is q/κ, whatever the angular discretization); the energy
// bookkeeping closes with the emitted power counted in `source`; 1 and all ranks agree.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tests/support/mpi_test.h"
#include "tests/verification/lpm/lpm_world.h"

namespace nimbus {
namespace {

using test::LpmWorld;
using test::lpm_options;

double blob(int i, int j, int k) {
    const double x = (i + 0.5) / 12.0 - 0.5, y = (j + 0.5) / 12.0 - 0.5, z = (k + 0.5) / 12.0 - 0.45;
    const double r2 = (x * x + y * y + z * z) / 0.16;
    return r2 < 1.0 ? 1.5 * (1.0 - r2) : 0.0;
}

std::vector<VolumeSource> sources_of(LpmWorld& w, std::vector<SourceSpec> specs) {
    w.scene.grid.cell_size = w.m.grid.h;
    w.scene.bands = w.m.bands;
    w.scene.sources = std::move(specs);
    return volume_sources(w.scene);
}

lpm::BandResult solve(const LpmWorld& w, const LpmOptions& o, const std::vector<VolumeSource>& sources) {
    const lpm::Angular a(o.p, o.k);
    return lpm::solve_band(w.d, w.m, w.light, 0, o, a, nullptr, nullptr, sources);
}

// A slab periodic in x and y, 16 cells of optical depth 1 thick, emitting everywhere, no
// scattering: 8 optical depths from either face the fluence is power/κ up to the light that
// leaves through the faces, (1/2) E_2(8) ≈ 2e-5 of it from each side.
TEST(LpmEmission, UniformSourceInAThickAbsorberGivesPowerOverKappa) {
    const double power = 2.5, kappa = 1.0;
    LpmWorld w(MPI_COMM_WORLD, {4, 4, 16}, {true, true, false}, [](int, int, int) { return 1.0; },
               BandOptics{"gray", kappa, 0.0, 0.0}, {});
    const auto src = sources_of(w, {SourceSpec{{0, 0, 0}, {4, 4, 16}, {power}}});
    const lpm::BandResult r = solve(w, lpm_options(3, 1, 1), src);
    EXPECT_NEAR(r.source, power * 4 * 4 * 16, 1e-12 * r.source);
    double err = 0.0;
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        if (k == 7 || k == 8) err = std::max(err, std::abs(r.fluence(i, j, k) / (power / kappa) - 1.0));
    });
    MPI_Allreduce(MPI_IN_PLACE, &err, 1, MPI_DOUBLE, MPI_MAX, w.d.comm());
    if (test::world_rank() == 0) std::printf("    uniform source, mid-slab: max |fluence kappa / power - 1| = %.2e\n", err);
    EXPECT_LT(err, 1e-4);
    EXPECT_NEAR(r.absorbed + r.escaped + r.truncated + r.remaining, r.source, 1e-12 * r.source);
}

// Sun and an emitting box in a scattering blob: the source counts the emitted power, and
// escaped + absorbed + remaining = source after any iteration count.
TEST(LpmEmission, BookkeepingCountsTheEmittedPower) {
    const DirectionalLight sun{"sun", normalized(Vec3{0.4, 0.25, -1.0}), {1.0}};
    LpmWorld w(MPI_COMM_WORLD, {12, 12, 12}, {false, false, false}, blob, BandOptics{"gray", 1.0, 0.7, 0.85}, {sun});
    const double power = 3.0;
    const auto src = sources_of(w, {SourceSpec{{4, 4, 3}, {8, 8, 7}, {power}}});
    const lpm::BandResult lit = solve(w, lpm_options(3, 3, 1), {});
    std::int64_t emitting = 0;
    for_each_cell(w.d.local(), [&](int i, int j, int k) { emitting += src[0].cells.contains(i, j, k) && w.m.rho(i, j, k) > 0; });
    MPI_Allreduce(MPI_IN_PLACE, &emitting, 1, MPI_INT64_T, MPI_SUM, w.d.comm());
    ASSERT_GT(emitting, 0);
    for (int it : {1, 2}) {
        const lpm::BandResult r = solve(w, lpm_options(3, 3, it), src);
        EXPECT_NEAR(r.source, lit.source + power * static_cast<double>(emitting), 1e-12 * r.source);
        EXPECT_NEAR(r.escaped + r.absorbed + r.remaining, r.source, 1e-12 * r.source);
    }
}

// The same answer on all ranks as on one (MPI_COMM_SELF), with the source split by the slabs.
TEST(LpmEmission, OneAndAllRanksAgreeToRoundOff) {
    const BandOptics band{"gray", 1.0, 0.8, 0.5};
    const std::vector<SourceSpec> specs = {SourceSpec{{3, 3, 2}, {9, 7, 10}, {1.5}}};
    LpmWorld all(MPI_COMM_WORLD, {12, 12, 12}, {false, false, false}, blob, band, {});
    LpmWorld one(MPI_COMM_SELF, {12, 12, 12}, {false, false, false}, blob, band, {});
    const lpm::BandResult ra = solve(all, lpm_options(3, 1, 3), sources_of(all, specs));
    const lpm::BandResult r1 = solve(one, lpm_options(3, 1, 3), sources_of(one, specs));
    double diff = 0.0, peak = 0.0;
    for_each_cell(all.d.local(), [&](int i, int j, int k) {
        diff = std::max(diff, std::abs(ra.fluence(i, j, k) - r1.fluence(i, j, k)));
        peak = std::max(peak, r1.fluence(i, j, k));
    });
    MPI_Allreduce(MPI_IN_PLACE, &diff, 1, MPI_DOUBLE, MPI_MAX, all.d.comm());
    MPI_Allreduce(MPI_IN_PLACE, &peak, 1, MPI_DOUBLE, MPI_MAX, all.d.comm());
    EXPECT_GT(peak, 0.0);
    EXPECT_LE(diff, 1e-12 * peak);
}

}  // namespace
}  // namespace nimbus
