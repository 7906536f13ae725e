// Sweeps confined to a region (SweepSource::region, TransportSweeper::region in
// solvers/dom/transport_sweep.h): the region is the bounding box of the cells with extinction or
// a source, whole along periodic axes, and none with a mirror face; a sweep of the region gives,
// inside it, the moments, fluence and flux of a sweep of the whole domain (the void around it
// only streams what the boundary sends in), 0 outside, under a sky radiance too, for step and
// diamond, octant overlap 1, 2 and 8, on 1, 2 and 3 ranks split along z and along x, with
// regions that cross rank boundaries, start on one, or miss some ranks; and after a sweep of the
// whole domain has left other values in the cells around the region.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "solvers/dom/angular_set.h"
#include "solvers/dom/transport_sweep.h"
#include "tests/support/mpi_test.h"
#include "tests/unit/sweep_engine/dom_test_source.h"

namespace nimbus::dom {
namespace {

constexpr Int3 kCells{10, 7, 12};

// A medium that absorbs inside `box` and scatters and is lit only inside `lit` (the whole box
// when empty), in vacuum: kappa, moments and a first-collision amplitude there, zero elsewhere.
struct BoxedMedium {
    Field<double> kappa, moments, amp;
    SourceRows rows;
    std::vector<double> packed;  // the moments of the rows' cells (SweepSource::moments)
    BoxedMedium(const Decomposition& d, const AngularSet& ang, const Box& box, const Box& lit = {}) {
        const Box& own = d.local();
        kappa = Field<double>(own, 0, 1, 0.0);
        moments = Field<double>(own, 0, ang.nmom, 0.0);
        amp = Field<double>(own, 0, 1, 0.0);
        for_each_cell(own.intersect(box), [&](int i, int j, int k) {
            kappa(i, j, k) = 0.3 + 0.05 * ((i + 2 * j + 3 * k) % 7);
            if (!lit.empty() && !lit.contains(i, j, k)) return;
            for (int m = 0; m < ang.nmom; ++m) moments(i, j, k, m) = (m == 0 ? 1.0 : 0.1 / (1 + m)) * (1.0 + 0.1 * i);
            amp(i, j, k) = std::exp(-0.2 * (kCells[2] - k));
        });
        rows = SourceRows(own, {&moments, &amp});
        const size_t nm = static_cast<size_t>(ang.nmom);
        packed.resize(rows.cells() * nm);
        rows.for_each_cell(
            [&](size_t c, size_t q) { std::copy_n(moments.data() + c * nm, nm, packed.data() + q * nm); });
    }
    BoxedMedium(const BoxedMedium&) = delete;
    BoxedMedium& operator=(const BoxedMedium&) = delete;
    SweepSource source(const AngularSet& ang, const Box* region) const {
        SweepSource s = test_source::make(ang, kappa, moments, amp);
        s.rows = &rows;
        s.moments = packed;
        s.region = region;
        return s;
    }
};

TEST(DomRegion, IsTheBoundingBoxOfTheMediumAndItsSources) {
    const AngularSet ang = make_angular_set(level_symmetric(4), 3);
    const Decomposition d(MPI_COMM_WORLD, kCells);
    sweep::SweepOptions opt;
    const Box box{{2, 1, 3}, {8, 6, 10}};
    const BoxedMedium m(d, ang, box);
    TransportSweeper open(d, ang, 1.0, opt, 1e-12);
    EXPECT_EQ(open.region(m.kappa, m.rows), std::optional<Box>(box));
    // An absorbing cell outside the sources widens it; a source cell without extinction too.
    Field<double> kappa = m.kappa;
    if (d.local().contains(0, 6, 11)) kappa(0, 6, 11) = 1e-3;
    EXPECT_EQ(open.region(kappa, m.rows), std::optional<Box>(Box{{0, 1, 3}, {8, 7, 12}}));
    Field<double> amp = m.amp;
    if (d.local().contains(9, 0, 0)) amp(9, 0, 0) = 1.0;
    EXPECT_EQ(open.region(m.kappa, SourceRows(d.local(), {&m.moments, &amp})),
              std::optional<Box>(Box{{2, 0, 0}, {10, 6, 10}}));
    // The whole domain: no region.
    Field<double> full(d.local(), 0, 1, 1.0);
    EXPECT_EQ(open.region(full, m.rows), std::nullopt);
    // Nothing at all: an empty region.
    const Field<double> none(d.local(), 0, 1, 0.0);
    const std::optional<Box> empty = open.region(none, SourceRows(d.local(), {&none}));
    ASSERT_TRUE(empty.has_value());
    EXPECT_TRUE(empty->empty());
    // A mirror face returns what leaves the region: no region.
    SweepBoundary mirror;
    mirror.reflective[3] = true;
    TransportSweeper mirrored(d, ang, 1.0, opt, 1e-12, SpatialScheme::step, mirror);
    EXPECT_EQ(mirrored.region(m.kappa, m.rows), std::nullopt);
    // Periodic axes are taken whole.
    const Decomposition p(MPI_COMM_WORLD, kCells, {1, 1, 0}, {true, false, false});
    const BoxedMedium mp(p, ang, box);
    TransportSweeper periodic(p, ang, 1.0, opt, 1e-12);
    EXPECT_EQ(periodic.region(mp.kappa, mp.rows), std::optional<Box>(Box{{0, 1, 3}, {10, 6, 10}}));
}

// A sweeper of unit cells, with a sky radiance of 0.7 or none; periodic planes to 1e-13.
TransportSweeper sweeper(const Decomposition& d, const AngularSet& ang, const sweep::SweepOptions& opt,
                         SpatialScheme scheme, bool sky) {
    SweepBoundary bc;
    bc.sky = sky;
    TransportSweeper s(d, ang, 1.0, opt, 1e-13, scheme, bc);
    s.set_sky_radiance(0.7);
    return s;
}

// out swept the region, ref the whole domain: inside the region the fields agree to round-off
// (relative to ref's largest value), outside out's are 0, and the moments on the rows agree.
void expect_region_sweep(const SweepOutput& out, const SweepOutput& ref, const Box& region, MPI_Comm comm,
                         const std::string& what) {
    double v[4] = {0.0, 0.0, 0.0, 0.0};  // max |diff| inside, max |out| outside, max |ref|, moments' diff
    for_each_cell(out.fluence.owned(), [&](int i, int j, int k) {
        const bool inside = region.contains(i, j, k);
        for (int c = 0; c < 4; ++c) {
            const double o = c == 0 ? out.fluence(i, j, k) : out.flux(i, j, k, c - 1);
            const double r = c == 0 ? ref.fluence(i, j, k) : ref.flux(i, j, k, c - 1);
            if (inside) v[0] = std::max(v[0], std::abs(o - r));
            else v[1] = std::max(v[1], std::abs(o));
            v[2] = std::max(v[2], std::abs(r));
        }
    });
    ASSERT_EQ(out.phi.size(), ref.phi.size()) << what;  // both packed on the same rows
    for (size_t q = 0; q < out.phi.size(); ++q) v[3] = std::max(v[3], std::abs(out.phi[q] - ref.phi[q]));
    MPI_Allreduce(MPI_IN_PLACE, v, 4, MPI_DOUBLE, MPI_MAX, comm);
    ASSERT_GT(v[2], 0.0) << what;
    EXPECT_LT(v[0] / v[2], 1e-13) << what << ": fields inside the region";
    EXPECT_EQ(v[1], 0.0) << what << ": fields outside the region";
    EXPECT_LT(v[3] / v[2], 1e-13) << what << ": moments";
}

TEST(DomRegion, SweepOfTheRegionIsTheWholeDomainsInsideIt) {
    const AngularSet ang = make_angular_set(level_symmetric(4), 3);
    // z 3..9 crosses every rank boundary of 2 and 3 slabs (6; 4, 8); 6..10 starts on the 2-slab
    // boundary and misses rank 0 there; 0..4 ends on the 3-slab boundary and misses the others.
    // The first box scatters only in part of it: its other rows absorb but have no source, so
    // their span is empty while the region's x range starts past the first cell.
    const Box boxes[] = {{{2, 1, 3}, {8, 6, 9}}, {{0, 2, 6}, {7, 7, 10}}, {{3, 0, 0}, {10, 5, 4}}};
    const Box lit[] = {{{4, 2, 4}, {7, 4, 8}}, {}, {}};
    for (const Int3 dims : {Int3{0, 0, 0}, Int3{test::world_size(), 1, 1}})  // z slabs; x split
        for (SpatialScheme scheme : {SpatialScheme::step, SpatialScheme::diamond})
            for (int overlap : {1, 2, 8})
                for (bool sky : {false, true})
                    for (size_t b = 0; b < std::size(boxes); ++b) {
                        const Box& box = boxes[b];
                        const Decomposition d(MPI_COMM_WORLD, kCells, dims);
                        const std::string what = d.describe() + ", " +
                                                 (scheme == SpatialScheme::step ? "step" : "diamond") + ", overlap " +
                                                 std::to_string(overlap) + (sky ? ", sky" : "") + ", box z " +
                                                 std::to_string(box.lo[2]) + ".." + std::to_string(box.hi[2]);
                        sweep::SweepOptions opt;
                        opt.tile_rows = 3;
                        opt.octant_overlap = overlap;
                        const BoxedMedium m(d, ang, box, lit[b]);
                        TransportSweeper whole = sweeper(d, ang, opt, scheme, sky), part = sweeper(d, ang, opt, scheme, sky);
                        const std::optional<Box> region = part.region(m.kappa, m.rows);
                        ASSERT_EQ(region, std::optional<Box>(box)) << what;
                        SweepOutput ref, out;
                        whole.sweep(m.source(ang, nullptr), ref);
                        part.sweep(m.source(ang, &*region), out);
                        expect_region_sweep(out, ref, box, d.comm(), what);
                        // A whole sweep leaves the light streamed through the void in the cells
                        // around the region; the next region sweep must not read it.
                        part.sweep(m.source(ang, nullptr), out);
                        part.sweep(m.source(ang, &*region), out);
                        expect_region_sweep(out, ref, box, d.comm(), what + ", after a whole sweep");
                    }
}

TEST(DomRegion, PeriodicAxesAreSweptWhole) {
    const AngularSet ang = make_angular_set(level_symmetric(4), 3);
    const Box box{{2, 1, 3}, {8, 6, 9}};
    for (SpatialScheme scheme : {SpatialScheme::step, SpatialScheme::diamond}) {
        const Decomposition d(MPI_COMM_WORLD, kCells, {1, 1, 0}, {true, false, false});
        const std::string what = d.describe() + (scheme == SpatialScheme::step ? ", step" : ", diamond");
        sweep::SweepOptions opt;
        opt.octant_overlap = 2;
        const BoxedMedium m(d, ang, box);
        TransportSweeper whole = sweeper(d, ang, opt, scheme, true), part = sweeper(d, ang, opt, scheme, true);
        const std::optional<Box> region = part.region(m.kappa, m.rows);
        ASSERT_TRUE(region.has_value());
        EXPECT_EQ(region->lo[0], 0);
        EXPECT_EQ(region->hi[0], kCells[0]);
        SweepOutput ref, out;
        whole.sweep(m.source(ang, nullptr), ref);
        part.sweep(m.source(ang, &*region), out);
        // The periodic planes iterate to a tolerance, not to round-off.
        double v[2] = {0.0, 0.0};
        for_each_cell(out.fluence.owned(), [&](int i, int j, int k) {
            if (region->contains(i, j, k)) v[0] = std::max(v[0], std::abs(out.fluence(i, j, k) - ref.fluence(i, j, k)));
            else EXPECT_EQ(out.fluence(i, j, k), 0.0) << what;
            v[1] = std::max(v[1], std::abs(ref.fluence(i, j, k)));
        });
        MPI_Allreduce(MPI_IN_PLACE, v, 2, MPI_DOUBLE, MPI_MAX, d.comm());
        EXPECT_LT(v[0] / v[1], 1e-10) << what;
    }
}

}  // namespace
}  // namespace nimbus::dom
