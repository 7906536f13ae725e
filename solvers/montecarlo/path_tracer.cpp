#include "solvers/montecarlo/path_tracer.h"

#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "src/core/empty_space.h"
#include "solvers/montecarlo/forward.h"
#include "src/core/error.h"
#include "src/core/gather.h"
#include "src/core/grid_walk.h"
#include "solvers/montecarlo/philox.h"
#include "src/core/log.h"
#include "src/core/progress.h"
#include "src/physics/phase.h"
#include "src/render/camera.h"
#include "src/render/source_kernel.h"
#include "src/scene/emission.h"
#include "src/scene/optics_groups.h"

namespace nimbus::mc {

namespace {

// Optical depth from s along s.d to the domain boundary (s is moved; pass a copy).
double optical_depth(const GridView& g, PathState s) {
    double tau = 0.0;
    walk_optical_depth(g, s, std::numeric_limits<double>::infinity(),
                       [&](std::int64_t idx, double len) { tau += g.voxel[idx].kappa * len; });
    return tau;
}

// Where the world ray x + t d first meets the domain box (grid units); false if it misses.
// g walks the whole domain (its box is the domain).
bool enter_domain(const Grid& grid, const GridView& g, const Vec3& x, const Vec3& d, PathState& s) {
    double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
    const Vec3 lo = grid.origin, hi = grid.upper();
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
            if (x[a] < lo[a] || x[a] > hi[a]) return false;
            continue;
        }
        double ta = (lo[a] - x[a]) / d[a], tb = (hi[a] - x[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    if (t0 >= t1) return false;
    const Vec3 p = x + d * t0;
    std::array<int, 3> cell{};
    for (int a = 0; a < 3; ++a) {
        const double u = std::clamp((p[a] - lo[a]) / grid.h, 0.0, static_cast<double>(grid.n[a]));
        cell[a] = std::min(static_cast<int>(u), grid.n[a] - 1);
        s.frac[a] = std::clamp(u - cell[a], 0.0, 1.0);
    }
    s.idx = g.index(cell);
    s.d = d;
    return true;
}

constexpr int kMaxBands = 64;  // bands per optics group (a radiance per band on the stack)

// A step through [0, n) that visits every index once, far from the next: i -> i stride mod n,
// stride coprime with n, near n / φ.
std::int64_t scramble_stride(std::int64_t n) {
    std::int64_t stride = std::max<std::int64_t>(1, static_cast<std::int64_t>(static_cast<double>(n) * 0.6180339887));
    while (std::gcd(stride, n) != 1) ++stride;
    return stride;
}

}  // namespace

Image path_trace_image(const SolveContext& ctx, const MonteCarloOptions& opt) {
    const Decomposition& d = ctx.decomp;
    const Medium& m = ctx.medium;
    const Scene& scene = ctx.scene;
    const Camera cam(scene.camera, m.grid);
    const int W = cam.width(), H = cam.height(), spp = opt.samples_per_pixel, nb = m.nbands();
    const std::vector<DirectionalLight>& lights = ctx.light.lights;
    const Int3 n = m.grid.n;
    const std::array<bool, 3> periodic{d.periodic(0), d.periodic(1), d.periodic(2)};
    const bool ground = scene.background.kind == BackgroundSpec::Kind::ground;
    if (ground && d.rank() == 0) log::warn("montecarlo image: background 'ground' is not modelled, rendered black");
    // Settings the path tracer does not read are said, as other ignored settings are (QA).
    if (scene.render.mode != RenderMode::scattering && d.rank() == 0)
        log::warn("montecarlo image: render.mode = '{}' is not used: the path-traced image is the full scattering "
                  "solution (set model.montecarlo.image = false for the ray caster's modes)",
                  to_string(scene.render.mode));
    if (spp == 1 && d.rank() == 0)
        log::warn("montecarlo image: samples_per_pixel = 1 gives no standard error: the stderr channels are written "
                  "as 0; use 2 or more");

    const std::vector<double> rho = allgather_global(m.rho, d);
    // Bands with equal optics share their paths (one walk per group, src/scene/optics_groups.h).
    const std::vector<OpticsGroup> groups = group_by_optics(m.bands);
    for (const OpticsGroup& G : groups)
        if (G.bands.size() > static_cast<size_t>(kMaxBands))
            throw Error(fmt::format("montecarlo image: at most {} bands with equal optics", kMaxBands));
    std::vector<VoxelGrid> voxels(groups.size());
    for (size_t gi = 0; gi < groups.size(); ++gi) {
        std::vector<float> k(rho.size());
        for (size_t c = 0; c < rho.size(); ++c) k[c] = static_cast<float>(rho[c] * groups[gi].optics.sigma_t * m.grid.h);
        voxels[gi] = make_voxels(n, k);
    }
    // Volume sources: q h per padded cell index and band (q = power / 4π, W/m³/sr, in covered
    // cells with density), so that q h len(cells) is the radiance a segment emits.
    const std::vector<VolumeSource> sources = volume_sources(scene);
    std::vector<std::vector<float>> q_h(sources.empty() ? 0 : static_cast<size_t>(nb));  // 4 B per cell and band
    for (int b = 0; b < static_cast<int>(q_h.size()); ++b) {
        std::vector<float>& q = q_h[static_cast<size_t>(b)];
        q.assign(static_cast<size_t>(voxels[0].padded_cells()), 0.0f);  // every group's grid has this layout
        const GridView g = voxels[0].view(periodic);
        for (const VolumeSource& src : sources)
            for_each_cell(src.cells, [&](int i, int j, int k) {
                if (rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] > 0)
                    q[static_cast<size_t>(g.index({i, j, k}))] +=
                        static_cast<float>(emission_radiance(src.power[static_cast<size_t>(b)]) * m.grid.h);
            });
    }

    // Per pixel and band: sum and sum of squares of the sample radiance; per pixel: alpha (mean).
    const std::int64_t pixels = static_cast<std::int64_t>(W) * H;
    std::vector<double> acc(static_cast<size_t>(pixels) * nb * 2 + static_cast<size_t>(pixels), 0.0);
    double* alpha = acc.data() + static_cast<size_t>(pixels) * nb * 2;
    // Tiles of kTile x kTile pixels go to the ranks in a scrambled order: visit v is tile
    // v stride mod tiles, on rank v mod size. Each rank then gets a like share of the cloud
    // wherever it sits in the image (contiguous blocks of samples gave one rank the top of the
    // image), the progress's ETA sees a representative mix of pixels from the start (it assumes
    // every pixel costs the same), the paths of a tile's neighbouring pixels keep sharing the
    // voxels in cache (single pixels in a scrambled order ran 1.2-1.5x slower), and each pixel's
    // sums are made on one rank in sample order: the image is the same for any rank count, bit
    // for bit.
    constexpr int kTile = 8;
    const int tiles_x = (W + kTile - 1) / kTile, tiles_y = (H + kTile - 1) / kTile;
    const std::int64_t tiles = static_cast<std::int64_t>(tiles_x) * tiles_y, stride = scramble_stride(tiles);
    // Calls f(x0, x1, y0, y1) for the pixel ranges of this rank's tiles, in its order.
    auto for_each_tile = [&](auto&& f) {
        for (std::int64_t v = d.rank(); v < tiles; v += d.size()) {
            const std::int64_t t = v * stride % tiles;
            const int x0 = static_cast<int>(t % tiles_x) * kTile, y0 = static_cast<int>(t / tiles_x) * kTile;
            f(x0, std::min(W, x0 + kTile), y0, std::min(H, y0 + kTile));
        }
    };
    std::int64_t mine = 0;  // this rank's samples
    for_each_tile([&](int x0, int x1, int y0, int y1) { mine += static_cast<std::int64_t>(x1 - x0) * (y1 - y0) * spp; });
    Progress progress("montecarlo image", static_cast<double>(mine), d.rank() == 0);
    std::int64_t done = 0;
    // Sample si = pixel spp + k of every band group.
    auto trace_sample = [&](std::int64_t si) {
        const std::int64_t pix = si / spp;
        const int px = static_cast<int>(pix % W), py = static_cast<int>(pix / W);
        for (size_t gi = 0; gi < groups.size(); ++gi) {
            // The group's bands differ only in their light: one path, a radiance per band.
            const std::vector<int>& bands = groups[gi].bands;
            const int nbg = static_cast<int>(bands.size());
            PathRng rng(opt.seed, 0x80000000u + static_cast<std::uint32_t>(bands[0]), static_cast<std::uint64_t>(si));
            // The camera sees the domain's one tile, as the ray caster does: its ray leaves at
            // the box's faces, periodic or not (wrapping, a horizontal view ray through a
            // periodic slab never left the medium). Scattered light lives in the periodic
            // medium: from the first collision on, paths and shadow rays wrap.
            const GridView g = voxels[gi].view(periodic), tile = voxels[gi].view({false, false, false});
            const BandOptics& o = groups[gi].optics;
            const Vec3 dir = cam.direction(px + rng.uniform(), py + rng.uniform());
            double L[kMaxBands]{};
            auto background = [&](double weight) {
                if (ground) return;
                for (int q = 0; q < nbg; ++q) L[q] += weight * band_value(scene.background.color, bands[static_cast<size_t>(q)]);
            };
            PathState s;
            if (!enter_domain(m.grid, g, cam.position(), dir, s)) {
                background(1.0);
            } else {
                // alpha = 1 - T over the pixel's samples, as the radiance (its bands' share of
                // the mean over bands); one ray through the pixel centre, as before, gave an
                // opaque alpha to a pixel whose samples mostly saw the background (QA).
                PathState view = s;
                alpha[pix] += (1.0 - std::exp(-optical_depth(tile, view))) * nbg / (static_cast<double>(nb) * spp);
                double beta = 1.0;
                bool scattered = false;
                for (;;) {
                    // Emission seen along the flight (track length: the flight reaches x with
                    // probability T(x), so sum q len = the expected integral of q T).
                    const double tau = -std::log(rng.uniform());
                    const GridView& walk = scattered ? g : tile;
                    const int face = q_h.empty() ? walk_optical_depth(walk, s, tau, [](std::int64_t, double) {})
                                                 : walk_optical_depth(walk, s, tau, [&](std::int64_t idx, double len) {
                                                       for (int q = 0; q < nbg; ++q)
                                                           L[q] += beta * q_h[static_cast<size_t>(bands[static_cast<size_t>(q)])]
                                                                             [static_cast<size_t>(idx)] * len;
                                                   });
                    if (face >= 0) {
                        if (!scattered) background(beta);
                        break;
                    }
                    scattered = true;
                    beta *= o.albedo;
                    if (beta <= 0.0) break;
                    for (const DirectionalLight& l : lights) {
                        PathState shadow = s;
                        shadow.d = -l.w;
                        const double c = beta * hg_phase(o.g, -dot(l.w, s.d)) * std::exp(-optical_depth(g, shadow));
                        for (int q = 0; q < nbg; ++q) L[q] += c * l.E0[static_cast<size_t>(bands[static_cast<size_t>(q)])];
                    }
                    if (beta < opt.roulette_weight) {
                        if (rng.uniform() < 0.5) beta *= 2.0; else break;
                    }
                    s.d = rotate_direction(s.d, hg_sample_mu(o.g, rng.uniform()), 2.0 * std::numbers::pi * rng.uniform());
                }
            }
            for (int q = 0; q < nbg; ++q) {
                const size_t b = static_cast<size_t>(bands[static_cast<size_t>(q)]);
                acc[(static_cast<size_t>(pix) * nb + b) * 2] += L[q];
                acc[(static_cast<size_t>(pix) * nb + b) * 2 + 1] += L[q] * L[q];
            }
        }
        if (++done % 4096 == 0) progress.update(static_cast<double>(done));
    };
    for_each_tile([&](int x0, int x1, int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int x = x0; x < x1; ++x) {
                const std::int64_t first = (static_cast<std::int64_t>(y) * W + x) * spp;
                for (int k = 0; k < spp; ++k) trace_sample(first + k);
            }
    });
    progress.finish();
    MPI_Reduce(d.rank() == 0 ? MPI_IN_PLACE : acc.data(), acc.data(), static_cast<int>(acc.size()), MPI_DOUBLE,
               MPI_SUM, 0, d.comm());
    if (d.rank() != 0) return {};

    Image img(W, H);
    img.stderr_rgb.assign(static_cast<size_t>(pixels) * 3, 0.0f);
    for (std::int64_t pix = 0; pix < pixels; ++pix) {
        float* rgba = &img.rgba[static_cast<size_t>(pix) * 4];
        for (int c = 0; c < 3; ++c) {
            const int b = nb == 3 ? c : 0;
            const double sum = acc[(static_cast<size_t>(pix) * nb + b) * 2], sum2 = acc[(static_cast<size_t>(pix) * nb + b) * 2 + 1];
            const double mean = sum / spp;
            const double var = spp > 1 ? std::max(0.0, sum2 / spp - mean * mean) * spp / (spp - 1) : 0.0;
            rgba[c] = static_cast<float>(mean);
            img.stderr_rgb[static_cast<size_t>(pix) * 3 + c] = static_cast<float>(std::sqrt(var / spp));
        }
        rgba[3] = static_cast<float>(alpha[pix]);
    }
    return img;
}

}  // namespace nimbus::mc
