// Driver of the parallel ray caster (contract in raycaster.h). Per rank:
//   1. source:    ViewVolume (rho and the view source J_b per cell, or its parts with shadowed
//                 lights, occupancy blocks)
//      balance:   slab decompositions move z-layers of the view volume between ranks so that
//                 each marches an equal share of the estimated samples (balance.h)
//   2. march:     for every pixel whose ray crosses the rank's box, integrate the steps this
//                 rank owns (march.h) into one fragment; ranks at the bottom also shade the
//                 ground where the ray meets it (ground.h)
//   3. composite: direct-send sort-last compositing, image gathered on rank 0 (composite.h)
#include "src/render/raycaster.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "src/core/error.h"
#include "src/physics/lights.h"
#include "src/render/balance.h"
#include "src/render/camera.h"
#include "src/render/composite.h"
#include "src/render/ground.h"
#include "src/render/march.h"
#include "src/render/march_source.h"
#include "src/render/ray_box.h"
#include "src/render/view_depth.h"
#include "src/render/view_volume.h"

namespace nimbus {
namespace {

using MarchFn = long (*)(const MarchView&, const RaySteps&, int, int, double, double*, double*);

MarchFn select_march(int nbands, bool attenuate) {
    if (nbands == 1) return attenuate ? &march_steps<1, true> : &march_steps<1, false>;
    if (nbands == 3) return attenuate ? &march_steps<3, true> : &march_steps<3, false>;
    return attenuate ? &march_steps<0, true> : &march_steps<0, false>;
}

MarchView make_march_view(const ViewVolume& v) {
    MarchView mv;
    mv.data = v.data.data();
    mv.sx = v.data.stride(0);
    mv.sy = v.data.stride(1);
    mv.sz = v.data.stride(2);
    mv.alo = v.data.allocated().lo;
    mv.n = v.grid.n;
    mv.owned = v.owned;
    mv.origin = v.grid.origin;
    mv.h = v.grid.h;
    mv.inv_h = 1.0 / v.grid.h;
    mv.occupied = v.occupied.data();
    mv.nblocks = v.nblocks;
    mv.block_shift = ViewVolume::kBlockShift;
    mv.nbands = v.nbands;
    mv.ncomp = v.data.ncomp();
    mv.split_lights = v.split_lights;
    mv.a_offset = v.a_offset;
    mv.log_t_offset = v.log_t_offset;
    mv.sigma_t = v.sigma_t.data();
    mv.radiance_bound = v.radiance_bound.data();
    mv.uniform_sigma = std::all_of(v.sigma_t.begin(), v.sigma_t.end(),
                                   [&](double s) { return s == v.sigma_t.front(); });
    return mv;
}

struct Box2 {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // pixels [x0, x1) x [y0, y1)
};

// The pixels whose rays can meet the world box [lo, hi]: the bounding rectangle of its
// projected corners plus a pixel of margin, or the whole image when a corner is not in front
// of the camera (the projection of a convex box is the hull of its corners').
Box2 image_rect(const Camera& cam, const Vec3& lo, const Vec3& hi) {
    const Box2 all{0, 0, cam.width(), cam.height()};
    double u0 = 1e300, v0 = 1e300, u1 = -1e300, v1 = -1e300;
    for (int c = 0; c < 8; ++c) {
        const Vec3 p{(c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z};
        double u, v;
        if (!cam.project(p, u, v)) return all;
        u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
    }
    auto clip = [](double t, int n) { return static_cast<int>(std::clamp(t, 0.0, static_cast<double>(n))); };
    return {clip(std::floor(u0) - 1, cam.width()), clip(std::floor(v0) - 1, cam.height()),
            clip(std::ceil(u1) + 1, cam.width()), clip(std::ceil(v1) + 1, cam.height())};
}

struct MarchStats {
    long fragments = 0, samples = 0, ground = 0;
};

// Per rank: the pixels and ray lattices of its box. setup_ray gives pixel (x, y)'s step range
// [m0, m1) on this rank (empty when the ray misses the occupied box).
struct RaySetup {
    const Camera& cam;
    const MarchView& view;
    const Box& live;
    bool any_live = false;
    Vec3 o, dom_lo, dom_hi, loc_lo, loc_hi;
    double ds_nominal = 1.0;

    RaySetup(const Camera& c, const ViewVolume& vol, const MarchView& v, const RenderSpec& rs)
        : cam(c), view(v), live(vol.occupied_cells) {
        const Grid& g = vol.grid;
        o = cam.position();
        dom_lo = g.origin;
        dom_hi = g.upper();
        // Only steps in the occupied part of the rank's box can contribute: the others sample
        // empty blocks. The box is grown by a hair so that rounding never drops a step: the
        // candidate range is padded anyway and then trimmed by the exact cell test, which (the
        // occupied box lying inside the owned box) also makes the ranks' pieces disjoint.
        any_live = !live.empty();
        const double eps = 1e-9 * g.h;
        for (int a = 0; a < 3; ++a) {
            loc_lo[a] = g.origin[a] + live.lo[a] * g.h - eps;
            loc_hi[a] = g.origin[a] + live.hi[a] * g.h + eps;
        }
        ds_nominal = rs.step * g.h;
    }

    bool setup_ray(int x, int y, RaySteps& r, int& m0, int& m1) const {
        r.o = o;
        r.d = cam.pixel_direction(x, y);
        double tg0, tg1, ta, tb;
        if (!(any_live && intersect_box(o, r.d, loc_lo, loc_hi, ta, tb) && tb > 0.0 &&
              intersect_box(o, r.d, dom_lo, dom_hi, tg0, tg1) && tg1 > 0.0))
            return false;
        r.t_enter = std::max(tg0, 0.0);
        const double chord = tg1 - r.t_enter;
        if (!(chord > 0.0)) return false;  // grazes an edge or a corner: no step (ds would be 0)
        r.n = std::max(1, static_cast<int>(std::ceil(chord / ds_nominal)));
        r.ds = chord / r.n;
        for (int a = 0; a < 3; ++a)
            r.inv_d[a] = r.d[a] != 0.0 ? 1.0 / r.d[a] : std::numeric_limits<double>::infinity();
        // Candidate steps: midpoints within [ta, tb], padded by one step each side.
        const double first = std::ceil((ta - r.t_enter) / r.ds - 0.5) - 1.0;
        const double last = std::floor((tb - r.t_enter) / r.ds - 0.5) + 2.0;
        m0 = static_cast<int>(std::clamp(first, 0.0, static_cast<double>(r.n)));
        m1 = static_cast<int>(std::clamp(last, 0.0, static_cast<double>(r.n)));
        while (m0 < m1 && !step_in(r, view, m0, live)) ++m0;
        while (m1 > m0 && !step_in(r, view, m1 - 1, live)) --m1;
        return m0 < m1;
    }
};

// Marches every pixel's ray through this rank's box and shades the ground it owns.
MarchStats march_image(const Camera& cam, const ViewVolume& vol, const GroundShading& ground,
                       const RenderSpec& rs, FragmentBuffer& out) {
    const MarchView view = make_march_view(vol);
    const int nb = vol.nbands;
    const MarchFn march = select_march(nb, rs.mode != RenderMode::emission);
    const RaySetup setup(cam, vol, view, rs);
    // Pixels whose ray can meet the occupied box: all when the ground is shaded here.
    Box2 px = ground.active() ? Box2{0, 0, cam.width(), cam.height()}
                              : setup.any_live ? image_rect(cam, setup.loc_lo, setup.loc_hi) : Box2{};
    MarchStats stats;
    double C[kMaxBands], T[kMaxBands], L[kMaxBands];
    for (int y = px.y0; y < px.y1; ++y) {
        for (int x = px.x0; x < px.x1; ++x) {
            const auto pixel = static_cast<std::int32_t>(static_cast<long long>(y) * cam.width() + x);
            RaySteps r;
            int m0 = 0, m1 = 0;
            if (setup.setup_ray(x, y, r, m0, m1)) {
                std::fill(C, C + nb, 0.0);
                std::fill(T, T + nb, 1.0);
                stats.samples += march(view, r, m0, m1, rs.early_termination, C, T);
                bool identity = true;
                for (int b = 0; b < nb; ++b) identity = identity && C[b] == 0.0 && T[b] == 1.0;
                if (!identity) {
                    out.add_segment(pixel, m0, C, T);
                    ++stats.fragments;
                }
            }
            if (ground.active() && ground.shade(setup.o, cam.pixel_direction(x, y), L)) {
                out.add_background(pixel, L);
                ++stats.ground;
            }
        }
    }
    return stats;
}

using DepthFn = void (*)(const MarchView&, const RaySteps&, int, int, double&, double&);
using SourceMarchFn = long (*)(const MarchView&, const RaySteps&, int, int, double, const ViewRaySource&,
                               const double*, double*, double*, ViewPathState&);

// march_image with a view-path source (view_source.h): a depth prepass over the rank's pieces,
// the exclusive scan of the depths in visibility order (view_depth.h), then the march.
MarchStats march_image_source(const Camera& cam, const ViewVolume& vol, const GroundShading& ground,
                              const RenderSpec& rs, const ViewRaySource& src,
                              const std::vector<double>& sigma_s, MPI_Comm comm, FragmentBuffer& out) {
    const MarchView view = make_march_view(vol);
    const int nb = vol.nbands;
    const DepthFn depth = nb == 1 ? &march_depth<1> : nb == 3 ? &march_depth<3> : &march_depth<0>;
    const SourceMarchFn march = nb == 1   ? &march_steps_source<1>
                                : nb == 3 ? &march_steps_source<3>
                                          : &march_steps_source<0>;
    const RaySetup setup(cam, vol, view, rs);
    Box2 px = setup.any_live ? image_rect(cam, setup.loc_lo, setup.loc_hi) : Box2{};
    // 1. Prepass: the depth sums of this rank's pieces. A ray that leaves the rank's box
    //    through the domain boundary has no piece behind this one: its sums are never read.
    const Grid& g = vol.grid;
    Vec3 own_lo, own_hi;
    for (int a = 0; a < 3; ++a) {
        own_lo[a] = g.origin[a] + vol.owned.lo[a] * g.h;
        own_hi[a] = g.origin[a] + vol.owned.hi[a] * g.h;
    }
    std::vector<PieceDepth> pieces;
    for (int y = px.y0; y < px.y1; ++y)
        for (int x = px.x0; x < px.x1; ++x) {
            RaySteps r;
            int m0 = 0, m1 = 0;
            if (!setup.setup_ray(x, y, r, m0, m1)) continue;
            PieceDepth p;
            p.pixel = static_cast<std::int32_t>(static_cast<long long>(y) * cam.width() + x);
            p.key = m0;
            double to0, to1, td0, td1;
            const bool last = intersect_box(r.o, r.d, own_lo, own_hi, to0, to1) &&
                              intersect_box(r.o, r.d, g.origin, g.upper(), td0, td1) && to1 >= td1 - 1e-9 * g.h;
            if (!last) depth(view, r, m0, m1, p.tau, p.s);
            pieces.push_back(p);
        }
    // 2. The depths at each piece's entry.
    const std::vector<std::array<double, 2>> entry = view_depth_at_entry(pieces, cam.width(), cam.height(), comm);
    // 3. The march (pieces without medium add nothing).
    MarchStats stats;
    double C[kMaxBands], T[kMaxBands], L[kMaxBands];
    size_t next = 0;
    for (int y = px.y0; y < px.y1; ++y)
        for (int x = px.x0; x < px.x1; ++x) {
            const auto pixel = static_cast<std::int32_t>(static_cast<long long>(y) * cam.width() + x);
            if (next >= pieces.size() || pieces[next].pixel != pixel) continue;
            RaySteps r;
            int m0 = 0, m1 = 0;
            setup.setup_ray(x, y, r, m0, m1);
            ViewPathState st;
            st.tau = entry[next][0];
            st.s = entry[next][1];
            ++next;
            std::fill(C, C + nb, 0.0);
            std::fill(T, T + nb, 1.0);
            stats.samples += march(view, r, m0, m1, rs.early_termination, src, sigma_s.data(), C, T, st);
            out.add_segment_held(pixel, m0, C, T, st.A, st.H_spec, st.H, st.has_spec, st.has_sample);
            ++stats.fragments;
        }
    if (ground.active()) {
        for (int y = 0; y < cam.height(); ++y)
            for (int x = 0; x < cam.width(); ++x) {
                const auto pixel = static_cast<std::int32_t>(static_cast<long long>(y) * cam.width() + x);
                if (ground.shade(cam.position(), cam.pixel_direction(x, y), L)) {
                    out.add_background(pixel, L);
                    ++stats.ground;
                }
            }
    }
    return stats;
}

}  // namespace

Image render_image(const RenderInputs& in, const Decomposition& d, Report& report) {
    ScopedTimer total(report, "render");
    const Scene& scene = in.scene;
    const int nb = in.medium.nbands();
    std::optional<Camera> camera;
    std::optional<GroundShading> ground;
    ViewVolume volume;
    run_collective(d.comm(), [&] {
        if (nb != 1 && nb != 3)
            throw Error("render: the image maps 1 band (gray) or 3 bands (rgb); the medium has " +
                        std::to_string(nb));
        const Grid& g = in.medium.grid;
        if (!(scene.render.step > 0) || norm(g.extent()) / (scene.render.step * g.h) > 1e8)
            throw Error("render.step must be > 0 and leave at most 1e8 steps along a ray");
        camera.emplace(scene.camera, in.medium.grid);
        ScopedTimer t(report, "source");
        volume = build_view_volume(in, d, camera->position());
    });
    ground.emplace(in, d);  // collective itself (an MPI_Allreduce): not inside run_collective
    std::vector<double> sky, ground_bound;
    for (int b = 0; b < nb; ++b) {
        sky.push_back(band_value(scene.background.color, b));
        ground_bound.push_back(ground->radiance_bound(b));
    }
    // A view-path source (view_source.h) only in mode scattering; its S term a_b H_max,b.
    ViewRaySource* source = scene.render.mode == RenderMode::scattering ? in.view_source : nullptr;
    std::vector<double> path;
    if (source) {
        double H[kMaxBands];
        source->radiance_bound(nb, H);
        for (int b = 0; b < nb; ++b) {
            const double a = in.medium.bands[static_cast<size_t>(b)].albedo;
            path.push_back(a > 0.0 ? a * H[b] : 0.0);  // a = 0: the source adds nothing (0 x inf)
        }
    }
    finish_radiance_bound(volume, sky, ground_bound, d, path);  // early termination's bound (march.h)
    report.values()["render"]["termination_bound"] = volume.radiance_bound;
    {
        ScopedTimer t(report, "balance");
        volume = balance_view_volume(std::move(volume), d, *camera);
    }

    if (source) {
        ScopedTimer t(report, "source_prepare");
        source->prepare(volume.owned, d);
    }
    FragmentBuffer fragments(nb, source != nullptr);
    MarchStats stats;
    {
        ScopedTimer t(report, "march");
        if (source) {
            std::vector<double> sigma_s;
            for (const auto& band : in.medium.bands) sigma_s.push_back(band.sigma_t * band.albedo);
            stats = march_image_source(*camera, volume, *ground, scene.render, *source, sigma_s, d.comm(), fragments);
        } else {
            stats = march_image(*camera, volume, *ground, scene.render, fragments);
        }
    }
    volume = ViewVolume{};  // free the march data before compositing

    Image image;
    {
        ScopedTimer t(report, "composite");
        image = composite_image(fragments, camera->width(), camera->height(), sky, d.comm());
    }
    long local[3] = {stats.samples, stats.fragments, stats.ground}, sum[3] = {0, 0, 0};
    MPI_Reduce(local, sum, 3, MPI_LONG, MPI_SUM, 0, d.comm());
    long max_samples = 0;
    MPI_Reduce(&stats.samples, &max_samples, 1, MPI_LONG, MPI_MAX, 0, d.comm());
    auto& v = report.values()["render"];
    v["samples"] = sum[0];
    v["samples_max_rank"] = max_samples;  // balance: samples_max_rank * ranks / samples
    v["fragments"] = sum[1];
    v["ground_pixels"] = sum[2];
    v["width"] = camera->width();
    v["height"] = camera->height();
    return image;
}

}  // namespace nimbus
