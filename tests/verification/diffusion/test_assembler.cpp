// The Assembler's rows, right-hand sides and fluxes against the face rules of diffusion_kernel.h
// written out per face from the cells' global coordinates (D form: D = 1/(3 max(kappa_tr, floor)),
// Marshak by ghost elimination 2Dh/(4D+h), (n·G)h²/(4D+h), U_f = (4D U_P - 2h n·G)/(4D+h)), on
// 1-3 ranks split along z or x, so that the Assembler's neighbours come from the ghost layer, the
// periodic images and the domain faces (Marshak, mirror, and a periodic axis one cell long, whose
// faces carry nothing). Guards the Assembler's reads by stride and its one look per cell at the
// faces for the row and every right-hand side.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>

#include "solvers/diffusion/assemble.h"
#include "src/core/halo.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

constexpr double kH = 0.5, kFloor = 0.05;

// About 30% of the cells empty, the others with kappa_tr in [0.01, 2] (some below the floor).
double kappa_at(int i, int j, int k) {
    std::uint32_t x = static_cast<std::uint32_t>(i * 73856093) ^ static_cast<std::uint32_t>(j * 19349663) ^
                      static_cast<std::uint32_t>(k * 83492791);
    x ^= x >> 13;
    x *= 0x5bd1e995u;
    x ^= x >> 15;
    if (x % 100 < 30) return 0.0;
    return 0.01 + 2.0 * static_cast<double>(x % 997) / 997.0;
}
double sigma_a_at(int i, int j, int k) { return 0.01 * (1 + (i + 2 * j + 3 * k) % 5); }
double q0_at(int r, int i, int j, int k) { return 1.0 + 0.1 * r + 0.05 * ((i * 7 + j * 3 + k) % 11); }
double g_at(int r, int i, int j, int k, int a) { return 0.3 * std::sin(1.0 + r + 0.7 * i - 0.4 * j + 0.9 * k + 2.0 * a); }
double u_at(int i, int j, int k) { return 2.0 + std::cos(0.3 * i + 0.5 * j - 0.2 * k); }

struct Domain {
    Int3 n;
    std::array<bool, 3> periodic;
    std::array<bool, 6> reflective;
};

// The face rules, per face, from global coordinates.
struct Reference {
    const Domain& s;
    bool full(int i, int j, int k) const { return kappa_at(i, j, k) > 0.0; }
    double capped(double k) const { return std::max(k, kFloor); }
    double G(int r, int i, int j, int k, int a) const {  // G consistent with the capped kappa_tr
        const double kt = kappa_at(i, j, k);
        return kt >= kFloor ? g_at(r, i, j, k, a) : g_at(r, i, j, k, a) * kt / kFloor;
    }
    enum Kind { kInterior, kMarshak, kMirror, kNothing };
    // What lies across face (a, side) of cell c; nb: the neighbour, wrapped where periodic.
    Kind across(const Int3& c, int a, int side, Int3& nb) const {
        nb = c;
        nb[a] += side;
        if (nb[a] < 0 || nb[a] >= s.n[a]) {
            if (!s.periodic[a]) return s.reflective[static_cast<size_t>(2 * a + (side > 0 ? 1 : 0))] ? kMirror : kMarshak;
            nb[a] = (nb[a] + s.n[a]) % s.n[a];
        }
        if (s.periodic[a] && s.n[a] == 1) return kNothing;
        return full(nb[0], nb[1], nb[2]) ? kInterior : kMarshak;
    }
    diffusion::CellRow row(int i, int j, int k) const {
        diffusion::CellRow row;
        row.diag = sigma_a_at(i, j, k) * kH * kH;
        const double kp = kappa_at(i, j, k);
        for (int a = 0; a < 3; ++a)
            for (int side : {-1, 1}) {
                Int3 nb;
                const Kind kind = across({i, j, k}, a, side, nb);
                const size_t e = static_cast<size_t>(2 * a + (side > 0 ? 1 : 0));
                if (kind == kInterior) {
                    const double Df = 1.0 / (3.0 * capped(0.5 * (kp + kappa_at(nb[0], nb[1], nb[2]))));
                    row.diag += Df;
                    row.coupling[e] = Df;
                } else if (kind == kMarshak) {
                    const double D = 1.0 / (3.0 * capped(kp));
                    row.diag += 2.0 * D * kH / (4.0 * D + kH);
                }
            }
        return row;
    }
    double rhs(int r, int i, int j, int k) const {
        double b = q0_at(r, i, j, k) * kH * kH;
        const double D = 1.0 / (3.0 * capped(kappa_at(i, j, k)));
        for (int a = 0; a < 3; ++a)
            for (int side : {-1, 1}) {
                Int3 nb;
                const Kind kind = across({i, j, k}, a, side, nb);
                if (kind == kInterior) b += -kH * side * 0.5 * (G(r, i, j, k, a) + G(r, nb[0], nb[1], nb[2], a));
                if (kind == kMarshak) b += (-side * G(r, i, j, k, a)) * kH * kH / (4.0 * D + kH);
            }
        return b;
    }
    Vec3 flux(int r, int i, int j, int k) const {
        Vec3 F;
        const double kp = kappa_at(i, j, k), D = 1.0 / (3.0 * capped(kp)), Up = u_at(i, j, k);
        for (int a = 0; a < 3; ++a) {
            double sum = 0.0;
            for (int side : {-1, 1}) {
                Int3 nb;
                const Kind kind = across({i, j, k}, a, side, nb);
                const double Gp = G(r, i, j, k, a);
                if (kind == kNothing) sum += Gp;
                if (kind == kInterior) {
                    const double Df = 1.0 / (3.0 * capped(0.5 * (kp + kappa_at(nb[0], nb[1], nb[2]))));
                    sum += 0.5 * (Gp + G(r, nb[0], nb[1], nb[2], a)) - Df * side * (u_at(nb[0], nb[1], nb[2]) - Up) / kH;
                }
                if (kind == kMarshak) {
                    const double n_dot_G = -side * Gp;
                    sum += side * 0.5 * (4.0 * D * Up - 2.0 * kH * n_dot_G) / (4.0 * D + kH);
                }
            }
            F[a] = 4.0 * std::numbers::pi * 0.5 * sum;
        }
        return F;
    }
};

void expect_face_rules(const Domain& s, const Int3& dims) {
    Decomposition d(MPI_COMM_WORLD, s.n, dims, s.periodic);
    diffusion::DiffusionProblem p;
    p.h = kH;
    p.n = s.n;
    p.periodic = s.periodic;
    p.reflective = s.reflective;
    p.kappa_tr = Field<double>(d.local(), 1, 1, 0.0);
    p.sigma_a = Field<double>(d.local(), 0, 1, 0.0);
    Field<double> U(d.local(), 1, 1, 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        p.kappa_tr(i, j, k) = kappa_at(i, j, k);
        p.sigma_a(i, j, k) = sigma_a_at(i, j, k);
        U(i, j, k) = u_at(i, j, k);
    });
    exchange_halo(p.kappa_tr, d);
    exchange_halo(U, d);
    constexpr int kRhs = 2;
    for (int r = 0; r < kRhs; ++r) {
        Field<double> q0(d.local(), 0, 1, 0.0), g(d.local(), 1, 3, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) {
            q0(i, j, k) = q0_at(r, i, j, k);
            for (int a = 0; a < 3; ++a) g(i, j, k, a) = g_at(r, i, j, k, a);
        });
        exchange_halo(g, d);
        p.Q0.push_back(std::move(q0));
        p.G.push_back(std::move(g));
    }
    const diffusion::Assembler as(p, kFloor);
    const Reference ref{s};
    const auto near = [](double got, double want) { return std::abs(got - want) <= 1e-13 * (1.0 + std::abs(want)); };
    int full = 0, bad = 0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const std::string at = "cell (" + std::to_string(i) + ", " + std::to_string(j) + ", " + std::to_string(k) + ")";
        double b[kRhs];
        const diffusion::CellRow row = as.row(i, j, k, b);
        if (!ref.full(i, j, k)) {  // an identity row, no right-hand side, no flux
            EXPECT_EQ(row.diag, 1.0) << at;
            for (int r = 0; r < kRhs; ++r) EXPECT_EQ(b[r], 0.0) << at;
            return;
        }
        ++full;
        const diffusion::CellRow want = ref.row(i, j, k);
        bool ok = near(row.diag, want.diag) && near(as.row(i, j, k).diag, want.diag);
        for (size_t e = 0; e < 6; ++e) ok = ok && near(row.coupling[e], want.coupling[e]);
        for (int r = 0; r < kRhs; ++r) {
            ok = ok && near(b[r], ref.rhs(r, i, j, k)) && near(as.rhs(r, i, j, k), ref.rhs(r, i, j, k));
            const Vec3 F = as.flux(r, U, i, j, k), Fw = ref.flux(r, i, j, k);
            for (int a = 0; a < 3; ++a) ok = ok && near(F[a], Fw[a]);
        }
        if (!ok && ++bad <= 3) ADD_FAILURE() << at << ": the Assembler differs from the face rules";
    });
    MPI_Allreduce(MPI_IN_PLACE, &full, 1, MPI_INT, MPI_SUM, d.comm());
    EXPECT_GT(full, s.n[0] * s.n[1] * s.n[2] / 2);  // a real test: most cells full
}

TEST(Assembler, FollowsTheFaceRulesOnEverySplitAndBoundary) {
    const int size = test::world_size();
    // Marshak on most domain faces, mirrors on x- and z+.
    const Domain open{{9, 7, 8}, {false, false, false}, {true, false, false, false, false, true}};
    // Periodic x, and y one cell long and periodic: its faces carry nothing.
    const Domain periodic{{9, 1, 8}, {true, true, false}, {false, false, false, false, true, false}};
    for (const Domain& s : {open, periodic})
        for (const Int3 dims : {Int3{1, 1, size}, Int3{size, 1, 1}}) {
            SCOPED_TRACE("grid " + std::to_string(s.n[0]) + "x" + std::to_string(s.n[1]) + "x" +
                         std::to_string(s.n[2]) + ", ranks along " + (dims[0] > 1 ? "x" : "z"));
            expect_face_rules(s, dims);
        }
}

}  // namespace
}  // namespace nimbus
