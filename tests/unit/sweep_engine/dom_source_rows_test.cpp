// Source rows in the DOM transport sweep (SourceRows, solvers/dom/transport_sweep.h): a sweep
// that builds sources and moments only on the spans of the rows where the source can be
// nonzero gives the same fluence, flux and leakage as a sweep over every cell, and the same
// moments on the spans' cells (the only ones it stores), for step and diamond, octant overlap 1, 2 and 8, on 1,
// 2 and 3 ranks split along z (slabs) and along x (the spans in global x indices), with spans
// that reach both ends of their rows; and a sweeper whose source buffers were last written with
// other rows (their cells outside the new spans nonzero) still gives the right answer.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "solvers/dom/angular_set.h"
#include "solvers/dom/transport_sweep.h"
#include "tests/unit/sweep_engine/dom_test_source.h"
#include "tests/support/mpi_test.h"

namespace nimbus::dom {
namespace {

TEST(DomSourceRows, SpansCoverTheNonzeroCellsOfEachRow) {
    const Box own{{2, 0, 0}, {10, 3, 2}};  // x 2..9, 3 rows in y, 2 layers
    Field<double> a(own, 0, 1, 0.0), b(own, 0, 2, 0.0);
    a(4, 0, 0) = 1.0;
    a(7, 0, 0) = -2.0;     // any nonzero value counts
    b(9, 0, 0, 1) = 1e-300;  // second component, another field
    b(3, 2, 1, 0) = 3.0;
    const SourceRows rows(own, {&a, &b});
    EXPECT_EQ(rows.lo(0, 0), 4);
    EXPECT_EQ(rows.hi(0, 0), 10);
    EXPECT_EQ(rows.lo(1, 0), rows.hi(1, 0));  // no nonzero cell
    EXPECT_EQ(rows.lo(2, 1), 3);
    EXPECT_EQ(rows.hi(2, 1), 4);
    EXPECT_TRUE(rows.contains(5, 0, 0));  // inside the span, though zero itself
    EXPECT_FALSE(rows.contains(3, 0, 0));
    EXPECT_FALSE(rows.contains(4, 2, 1));
    EXPECT_DOUBLE_EQ(rows.fraction(), 7.0 / 48.0);
    EXPECT_EQ(rows.cells(), 7u);
    // Offsets in a ghost-free field on own (x fastest, 8 x 3 per layer) and packed places.
    std::vector<size_t> offsets, places;
    rows.for_each_cell([&](size_t c, size_t q) {
        offsets.push_back(c);
        places.push_back(q);
    });
    EXPECT_EQ(offsets, (std::vector<size_t>{2, 3, 4, 5, 6, 7, 24 + 2 * 8 + 1}));
    EXPECT_EQ(places, (std::vector<size_t>{0, 1, 2, 3, 4, 5, 6}));
    EXPECT_TRUE(rows == SourceRows(own, {&b, &a}));
    EXPECT_FALSE(rows == SourceRows(own, {&a}));
}

// A blob of scattering medium (moments and a first-collision amplitude) centred at cx in an
// absorbing medium (kappa > 0 everywhere), on the 10 x 7 x 8 grid.
struct Blob {
    Field<double> kappa, moments, amp;
    SweepSource src;  // every cell
    SourceRows rows;
    std::vector<double> packed;  // the moments of the rows' cells, packed (SweepSource::moments)
    Blob(const Decomposition& d, const AngularSet& ang, int cx) {
        const Box& own = d.local();
        kappa = Field<double>(own, 0, 1, 0.0);
        moments = Field<double>(own, 0, ang.nmom, 0.0);
        amp = Field<double>(own, 0, 1, 0.0);
        for_each_cell(own, [&](int i, int j, int k) {
            kappa(i, j, k) = 0.3 + 0.05 * ((i + 2 * j + 3 * k) % 7);
            const double r2 = (i - cx) * (i - cx) + (j - 3) * (j - 3) + (k - 4) * (k - 4);
            if (r2 > 6.0) return;
            for (int m = 0; m < ang.nmom; ++m) moments(i, j, k, m) = (m == 0 ? 1.0 : 0.1 / (1 + m)) * (1.0 + 0.1 * i);
            amp(i, j, k) = std::exp(-0.2 * (d.global().hi[2] - k));
        });
        rows = SourceRows(own, {&moments, &amp});
        src = test_source::make(ang, kappa, moments, amp);
        const size_t nm = static_cast<size_t>(ang.nmom);
        packed.resize(rows.cells() * nm);
        rows.for_each_cell(
            [&](size_t c, size_t q) { std::copy_n(moments.data() + c * nm, nm, packed.data() + q * nm); });
    }
    Blob(const Blob&) = delete;  // src and its rows point into this Blob
    Blob& operator=(const Blob&) = delete;
    SweepSource with_rows() const {
        SweepSource s = src;
        s.rows = &rows;
        s.moments = packed;
        return s;
    }
};

// out was swept with rows (null: every cell), ref over every cell: out's moments, packed on the
// rows' cells, are ref's there (relative to ref's largest moment, max over ranks).
double rel_diff_moments(const SweepOutput& out, const SweepOutput& ref, const SourceRows* rows, int nmom,
                        MPI_Comm comm) {
    const size_t nm = static_cast<size_t>(nmom);
    const SourceRows every(ref.fluence.owned());
    double v[2] = {0.0, 0.0};
    EXPECT_EQ(out.phi.size(), (rows ? rows : &every)->cells() * nm);
    (rows ? rows : &every)->for_each_cell([&](size_t c, size_t q) {
        for (size_t k = 0; k < nm; ++k) v[0] = std::max(v[0], std::abs(out.phi[q * nm + k] - ref.phi[c * nm + k]));
    });
    for (double x : ref.phi) v[1] = std::max(v[1], std::abs(x));
    MPI_Allreduce(MPI_IN_PLACE, v, 2, MPI_DOUBLE, MPI_MAX, comm);
    return v[0] / v[1];
}

// rows: the rows out was swept with, null for every cell.
void expect_same_sweep(const SweepOutput& out, const SweepOutput& ref, const SourceRows* rows, int nmom,
                       MPI_Comm comm, const std::string& what) {
    EXPECT_LT(rel_diff_moments(out, ref, rows, nmom, comm), 1e-14) << what;
    EXPECT_LT(test_source::rel_diff(out.fluence, ref.fluence, ref.fluence, comm), 1e-14) << what;
    EXPECT_LT(test_source::rel_diff(out.flux, ref.flux, ref.fluence, comm), 1e-14) << what;
    for (size_t f = 0; f < 6; ++f)
        EXPECT_NEAR(out.leakage[f], ref.leakage[f], 1e-13 * (1.0 + std::abs(ref.leakage[f]))) << what << ", face " << f;
}

TEST(DomSourceRows, SweepOnTheSpansEqualsTheSweepOverEveryCell) {
    const AngularSet ang = make_angular_set(level_symmetric(4), 3);
    for (const Int3 dims : {Int3{0, 0, 0}, Int3{test::world_size(), 1, 1}})  // z slabs; x split
    for (SpatialScheme scheme : {SpatialScheme::step, SpatialScheme::diamond})
        for (int overlap : {1, 2, 8}) {
            const Decomposition d(MPI_COMM_WORLD, {10, 7, 8}, dims, {false, false, false});
            const std::string what = d.describe() + ", " + (scheme == SpatialScheme::step ? "step" : "diamond") +
                                     ", overlap " + std::to_string(overlap);
            sweep::SweepOptions opt;
            opt.tile_rows = 3;
            opt.octant_overlap = overlap;
            // x 0..3 and 6..9: spans from the first and to the last cell of their rows
            const Blob left(d, ang, 1), right(d, ang, 8);
            ASSERT_LT(left.rows.fraction(), 0.5);
            TransportSweeper every(d, ang, 1.0, opt, 1e-12, scheme), spans(d, ang, 1.0, opt, 1e-12, scheme);
            SweepOutput ref, out;
            every.sweep(left.src, ref);
            spans.sweep(left.with_rows(), out);
            expect_same_sweep(out, ref, &left.rows, ang.nmom, d.comm(), what + ", left blob");
            // The same sweeper, now with other rows: its source buffers hold the left blob's
            // sources, nonzero outside the right blob's spans.
            every.sweep(right.src, ref);
            spans.sweep(right.with_rows(), out);
            expect_same_sweep(out, ref, &right.rows, ang.nmom, d.comm(), what + ", then the right blob");
            // The same rows again (the buffers' zeros outside the spans are kept, not rewritten).
            every.sweep(right.src, ref);
            spans.sweep(right.with_rows(), out);
            expect_same_sweep(out, ref, &right.rows, ang.nmom, d.comm(), what + ", the right blob again");
            // Every cell (rows = null), then spans once more.
            every.sweep(left.src, ref);
            spans.sweep(left.src, out);
            expect_same_sweep(out, ref, nullptr, ang.nmom, d.comm(), what + ", every cell after spans");
            every.sweep(right.src, ref);
            spans.sweep(right.with_rows(), out);
            expect_same_sweep(out, ref, &right.rows, ang.nmom, d.comm(), what + ", spans after every cell");
        }
}

}  // namespace
}  // namespace nimbus::dom
