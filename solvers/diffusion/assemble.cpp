#include "solvers/diffusion/assemble.h"

#include <algorithm>
#include <numbers>

namespace nimbus::diffusion {

Assembler::CellFaces Assembler::faces(int i, int j, int k) const {
    CellFaces f;
    const Field<double>& K = p_.kappa_tr;
    const double* kc = &K(i, j, k);
    f.kt = *kc;
    f.floor = floor_at(i, j, k);
    const int c[3] = {i, j, k};
    for (int e = 0; e < 6; ++e) {
        const int axis = e / 2, s = e % 2 == 0 ? -1 : 1, nb = c[axis] + s;
        FaceInput& in = f.in[static_cast<size_t>(e)];
        in.kappa_floor = f.floor;
        if ((nb < 0 || nb >= p_.n[axis]) && !p_.periodic[axis]) {  // domain boundary: Marshak, or a mirror
            in.mirror = p_.reflective[static_cast<size_t>(e)];
        } else if (p_.periodic[axis] && p_.n[axis] == 1) {
            f.skip[static_cast<size_t>(e)] = true;
            continue;
        } else if (const double kt = kc[s * K.stride(axis)]; kt > 0.0) {
            // Inside, or a periodic image held in the (wrapped) ghost layer.
            in.neighbor_full = true;
            in.kappa_tr_n = kt;
        }
        f.coef[static_cast<size_t>(e)] = face_coefficient(f.kt, in, p_.h);
    }
    return f;
}

CellRow Assembler::row(int i, int j, int k) const { return row(i, j, k, {}); }

CellRow Assembler::row(int i, int j, int k, std::span<double> b) const {
    CellRow row;
    if (!full(i, j, k)) {
        std::fill(b.begin(), b.end(), 0.0);
        return row;
    }
    const CellFaces f = faces(i, j, k);
    const double h = p_.h;
    row.diag = p_.sigma_a(i, j, k) * h * h;
    for (size_t e = 0; e < 6; ++e) {
        row.diag += f.coef[e];  // 0 on a skipped face
        if (f.in[e].neighbor_full) row.coupling[e] = f.coef[e];
    }
    for (size_t r = 0; r < b.size(); ++r) b[r] = rhs(static_cast<int>(r), i, j, k, f);
    return row;
}

bool Assembler::has_marshak_face(int i, int j, int k) const {
    if (!full(i, j, k)) return false;  // an empty cell has no floor (it is in no piece)
    const CellFaces f = faces(i, j, k);
    for (int e = 0; e < 6; ++e) {
        const FaceInput& in = f.in[static_cast<size_t>(e)];
        if (!in.neighbor_full && !in.mirror && !f.skip[static_cast<size_t>(e)]) return true;
    }
    return false;
}

double Assembler::rhs(int r, int i, int j, int k) const {
    return full(i, j, k) ? rhs(r, i, j, k, faces(i, j, k)) : 0.0;
}

double Assembler::rhs(int r, int i, int j, int k, const CellFaces& f) const {
    const Field<double>& G = p_.G[static_cast<size_t>(r)];
    const double* g = &G(i, j, k);  // component a at g[a], the neighbour's at ± G.stride
    const double h = p_.h;
    double b = p_.Q0[static_cast<size_t>(r)](i, j, k) * h * h;
    for (int e = 0; e < 6; ++e) {
        if (f.skip[static_cast<size_t>(e)]) continue;
        const int axis = e / 2, s = e % 2 == 0 ? -1 : 1;
        b += face_rhs(f.kt, G_eff(g[axis], f.kt, f.floor), s, with_neighbor_G(G, g, f, e),
                      f.coef[static_cast<size_t>(e)], h);
    }
    return b;
}

Vec3 Assembler::flux(int r, const Field<double>& U, int i, int j, int k) const {
    Vec3 F;
    if (!full(i, j, k)) return F;
    const CellFaces f = faces(i, j, k);
    const Field<double>& G = p_.G[static_cast<size_t>(r)];
    const double* g = &G(i, j, k);
    const double* u = &U(i, j, k);
    const double h = p_.h;
    for (int axis = 0; axis < 3; ++axis) {
        const double Gp = G_eff(g[axis], f.kt, f.floor);
        double sum = 0.0;
        for (int e = 2 * axis; e < 2 * axis + 2; ++e) {
            if (f.skip[static_cast<size_t>(e)]) {
                sum += Gp;
                continue;
            }
            const int s = e % 2 == 0 ? -1 : 1;
            const FaceInput in = with_neighbor_G(G, g, f, e);
            const double Un = in.neighbor_full ? u[s * U.stride(axis)] : 0.0;
            sum += face_flux(f.kt, Gp, *u, s, in, Un, f.coef[static_cast<size_t>(e)], h);
        }
        if (!p_.escape_flux.empty()) sum += p_.escape_flux[static_cast<size_t>(r)](i, j, k, axis);
        F[axis] = 4.0 * std::numbers::pi * 0.5 * sum;
    }
    return F;
}

}  // namespace nimbus::diffusion
