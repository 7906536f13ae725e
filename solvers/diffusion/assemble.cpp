#include "solvers/diffusion/assemble.h"

#include <numbers>

namespace nimbus::diffusion {

FaceInput Assembler::neighbor(int r, int axis, int s, const Int3& c, Int3& nb, bool& skip) const {
    nb = c;
    nb[axis] += s;
    skip = false;
    FaceInput in;
    in.kappa_floor = floor_at(c[0], c[1], c[2]);
    const bool outside = nb[axis] < 0 || nb[axis] >= p_.n[axis];
    if (outside && !p_.periodic[axis]) {  // domain boundary: Marshak, or a mirror
        in.mirror = p_.reflective[static_cast<size_t>(2 * axis + (s > 0 ? 1 : 0))];
        return in;
    }
    if (p_.periodic[axis] && p_.n[axis] == 1) {
        skip = true;
        return in;
    }
    // Inside, or a periodic image held in the (wrapped) ghost layer.
    const double kt = p_.kappa_tr(nb[0], nb[1], nb[2]);
    if (kt > 0.0) {
        in.neighbor_full = true;
        in.kappa_tr_n = kt;
        if (r >= 0) in.G_n = G_eff(r, nb[0], nb[1], nb[2], axis, in.kappa_floor);
    }
    return in;
}

CellRow Assembler::row(int i, int j, int k) const {
    CellRow row;
    if (!full(i, j, k)) return row;
    const double kt = p_.kappa_tr(i, j, k), h = p_.h;
    row.diag = p_.sigma_a(i, j, k) * h * h;
    const Int3 c{i, j, k};
    for (int axis = 0; axis < 3; ++axis) {
        for (int s : {-1, +1}) {
            Int3 nb;
            bool skip = false;
            const FaceInput in = neighbor(-1, axis, s, c, nb, skip);
            if (skip) continue;
            const FaceTerms t = face_terms(kt, 0.0, s, in, h);
            row.diag += t.diag;
            row.coupling[static_cast<size_t>(2 * axis + (s > 0 ? 1 : 0))] = t.coupling;
        }
    }
    return row;
}

bool Assembler::has_marshak_face(int i, int j, int k) const {
    if (!full(i, j, k)) return false;  // an empty cell has no floor (it is in no piece)
    const Int3 c{i, j, k};
    for (int axis = 0; axis < 3; ++axis)
        for (int s : {-1, +1}) {
            Int3 nb;
            bool skip = false;
            const FaceInput in = neighbor(-1, axis, s, c, nb, skip);
            if (!in.neighbor_full && !in.mirror && !skip) return true;
        }
    return false;
}

double Assembler::rhs(int r, int i, int j, int k) const {
    if (!full(i, j, k)) return 0.0;
    const double kt = p_.kappa_tr(i, j, k), h = p_.h;
    double b = p_.Q0[static_cast<size_t>(r)](i, j, k) * h * h;
    const Int3 c{i, j, k};
    for (int axis = 0; axis < 3; ++axis) {
        for (int s : {-1, +1}) {
            Int3 nb;
            bool skip = false;
            const FaceInput in = neighbor(r, axis, s, c, nb, skip);
            if (skip) continue;
            b += face_terms(kt, G_eff(r, i, j, k, axis, in.kappa_floor), s, in, h).rhs;
        }
    }
    return b;
}

Vec3 Assembler::flux(int r, const Field<double>& U, int i, int j, int k) const {
    Vec3 F;
    if (!full(i, j, k)) return F;
    const double kt = p_.kappa_tr(i, j, k), h = p_.h;
    const Int3 c{i, j, k};
    const double floor = floor_at(i, j, k);
    for (int axis = 0; axis < 3; ++axis) {
        const double Gp = G_eff(r, i, j, k, axis, floor);
        double sum = 0.0;
        for (int s : {-1, +1}) {
            Int3 nb;
            bool skip = false;
            const FaceInput in = neighbor(r, axis, s, c, nb, skip);
            const double Un = in.neighbor_full ? U(nb[0], nb[1], nb[2]) : 0.0;
            sum += skip ? Gp : face_flux(kt, Gp, U(i, j, k), s, in, Un, h);
        }
        if (!p_.escape_flux.empty()) sum += p_.escape_flux[static_cast<size_t>(r)](i, j, k, axis);
        F[axis] = 4.0 * std::numbers::pi * 0.5 * sum;
    }
    return F;
}

}  // namespace nimbus::diffusion
