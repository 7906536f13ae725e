#include "solvers/dom/angular_set.h"

#include <cmath>

namespace nimbus::dom {

AngularSet make_angular_set(const Quadrature& q, int L) {
    AngularSet s;
    s.quadrature = q;
    s.L = L;
    const MomentOperator op = make_moment_operator(q, L);
    s.nmom = op.nmom;
    s.degree = op.degree;
    for (int o = 0; o < 8; ++o)
        s.octants[static_cast<size_t>(o)].octant = sweep::Octant{{o & 1 ? 1 : -1, o & 2 ? 1 : -1, o & 4 ? 1 : -1}};
    auto octant_of = [](const Vec3& w) {
        const sweep::Octant o = sweep::Octant::of(w);
        return (o.s[0] > 0 ? 1 : 0) + (o.s[1] > 0 ? 2 : 0) + (o.s[2] > 0 ? 4 : 0);
    };
    for (int n = 0; n < q.size(); ++n) {
        auto& oc = s.octants[static_cast<size_t>(octant_of(q.dir[static_cast<size_t>(n)]))];
        oc.index.push_back(n);
    }
    for (auto& oc : s.octants) {
        const int nd = oc.size();
        s.max_octant_size = std::max(s.max_octant_size, nd);
        for (auto& a : oc.abs_mu) a.resize(static_cast<size_t>(nd));
        oc.weight.resize(static_cast<size_t>(nd));
        oc.dir.resize(static_cast<size_t>(nd));
        oc.Y.resize(static_cast<size_t>(s.nmom * nd));
        oc.wY.resize(static_cast<size_t>(s.nmom * nd));
        for (int c = 0; c < nd; ++c) {
            const int n = oc.index[static_cast<size_t>(c)];
            const Vec3& w = q.dir[static_cast<size_t>(n)];
            oc.dir[static_cast<size_t>(c)] = w;
            for (int a = 0; a < 3; ++a) oc.abs_mu[static_cast<size_t>(a)][static_cast<size_t>(c)] = std::abs(w[a]);
            oc.weight[static_cast<size_t>(c)] = q.weight[static_cast<size_t>(n)];
            for (int k = 0; k < s.nmom; ++k) {
                oc.Y[static_cast<size_t>(k * nd + c)] = op.m2d[static_cast<size_t>(n * s.nmom + k)];
                oc.wY[static_cast<size_t>(k * nd + c)] = op.d2m[static_cast<size_t>(k * op.ndir + n)];
            }
        }
    }
    return s;
}

AngularSet make_angular_set(const DomOptions& opt) {
    return make_angular_set(make_quadrature(opt), opt.legendre_order);
}

}  // namespace nimbus::dom
