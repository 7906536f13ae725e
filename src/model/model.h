// The one interface every multiple-scattering model implements (DESIGN §2). The pipeline
// calls solve() without knowing which model runs; each model fills a DiffuseSolution whose
// fluence has the same meaning everywhere:
//   fluence_diffuse = ∫ I_d dw = 4π U   (W/m², per band, on the rank's owned box)
// The renderer evaluates the in-scattered radiance toward w from it (DESIGN §1):
//   J(x, w) = kappa a [ ∫ p I_d dw' + Σ_lights E0 T p(w·w_light) ]
// with ∫ p I_d dw' = fluence/(4π) where the model gives no flux, and otherwise rebuilt from the
// fluence and the flux F by the model's closure (src/physics/radiance_closure.h): P1's
// fluence/(4π) + (3 g / 4π) F·w for diffusion, a realizable shape for transport models.
#pragma once

#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "src/core/decomposition.h"
#include "src/core/exp_neg.h"
#include "src/core/field.h"
#include "src/core/report.h"
#include "src/model/options.h"
#include "src/physics/lights.h"
#include "src/physics/radiance_closure.h"
#include "src/render/image.h"
#include "src/scene/medium.h"
#include "src/scene/scene.h"

namespace nimbus {

// What the light pass produced: per light term, the optical depth of the density along the
// light's path, tau_rho(x) = ∫ rho ds from x back to the domain boundary against w (metres ×
// density). Per band, T = exp(-sigma_t tau_rho). Owned box + 1 ghost layer (halo-exchanged).
struct LightTransport {
    std::vector<DirectionalLight> lights;
    std::vector<Field<double>> tau_rho;  // one per light

    double transmittance(int light, double sigma_t, int i, int j, int k) const {
        return std::exp(-sigma_t * tau_rho[static_cast<size_t>(light)](i, j, k));
    }
    // The mean of T over cell (i, j, k) of density rho (metres h), for the first-scatter source of
    // a cell-centred scheme, whose cell integrates kappa a E0 T: T at the centre is a midpoint
    // rule, 4% low at kappa h = 1 and e^{-50}/(1/100) off at kappa h = 100 (vertical sun). With
    // tau linear across the cell, <e^{-tau}> = e^{-tau_c} Π_a sinh(h g_a / 2) / (h g_a / 2),
    // g = sigma_t ∇tau_rho: along the light exactly rho sigma_t (w·∇tau_rho = rho), across it
    // from central differences of the neighbours' tau_rho, one-sided at a domain face and next
    // to an empty neighbour (where tau_rho bends: the surface of a cloud); never above what the
    // cell can remove from the beam, Σ|w_a| / (kappa h), nor above 1. Exact for a homogeneous
    // medium under a plane boundary; d gives the domain and periodic axes, rho the density with
    // its ghost layer.
    // Where a face the light enters the cell by has no medium beyond it, the light entering
    // there alone gives T_beyond face_mean(w, a, kappa h), and the mean is never below their sum.
    double transmittance_mean(const Decomposition& d, const Field<double>& rho, int light, double sigma_t, double h,
                              int i, int j, int k) const;
    // T (at sigma_t) arriving at the face on axis a by which the light enters cell (i, j, k),
    // where no medium lies beyond that face: T of the empty cell beyond it, or 1 beyond a
    // non-periodic domain face (tau_rho is 0 there). -1 where the cell beyond has density or the
    // light runs parallel to the face. rho with its ghost layer.
    double transmittance_beyond(const Decomposition& d, const Field<double>& rho, int light, double sigma_t, int i,
                                int j, int k, int a) const;
    // The mean over a homogeneous cube of optical thickness lambda = kappa h of T from the light
    // (|w| = 1) entering by its face on axis a at T = 1 uniformly, over the points whose ray back
    // toward the light leaves by that face: with u the path from the face in units of h,
    //   |w_a| ∫_0^U e^{-lambda u} Π_{b != a} (1 - |w_b| u) du,   U = 1 / max_c |w_c|.
    // The three faces' sum is 1 at lambda = 0 and |w_a| / lambda for a thick cube.
    static double face_mean(const Vec3& w, int a, double lambda);
    // The cell mean of T' - T, T' = e^{-sigma_scaled tau} and T = e^{-sigma_t tau} (sigma_scaled <
    // sigma_t): the light a delta-scaled model (diffusion's delta-Eddington, dom's delta-M) keeps
    // in its reduced beam beyond the true one, its forward peak, which fluence_diffuse adds back.
    // In a cell with density the difference of the two means of transmittance_mean's profile
    // (its gradient scaled so that tau_rho >= 0 everywhere in the cell: on a staircase surface the
    // neighbours' one-sided differences are no gradient), never below the T' - T of the light
    // entering by the faces with nothing beyond them, nor above transmittance_mean's bound (test
    // ForwardPeakOnAStaircaseSphereStaysNearTheCellsMean): a cell-centred model's source integrates the cell's mean
    // of T', and its fluence is a cell mean too (Monte Carlo's is); T' - T at the centre put the
    // peak of a lit cell at kappa h = 20 (delta-Eddington f = 0.72) 3x too low, and 10% too high
    // at kappa h = 1. In an empty cell T is constant along the light and the centre's T' - T is
    // kept (across the light it varies as a shadow does; the means there tripled the cost of the
    // diffusion model's band fields on the default cloud, 0.04 -> 0.15 s). 0 where the light has
    // crossed no medium (tau_rho = 0 at the centre). Not scaled by FirstScatterMeans' bound.
    // Inline: the empty cells' answer is a lookup or two exps (the bench cumulus at 64³ has 230 000
    // empty cells and 32 000 full ones; with profile()'s reads by stride, diffusion's forward peak
    // went from 6.0 to 4.5 ms).
    double forward_peak_mean(const Decomposition& d, const Field<double>& rho, int light, double sigma_t,
                             double sigma_scaled, double h, int i, int j, int k) const {
        const double tau = tau_rho[static_cast<size_t>(light)](i, j, k);
        if (tau == 0.0) return 0.0;
        if (!(rho(i, j, k) > 0.0)) return exp_neg(sigma_scaled * tau) - exp_neg(sigma_t * tau);
        return forward_peak_in_medium(d, rho, light, sigma_t, sigma_scaled, h, i, j, k);
    }
    // Where add_forward_peak puts the lights' forward peaks: fluence += Σ_l e0[l] <T' - T>_l and,
    // if given, flux (3 components) += Σ_l e0[l] <T' - T>_l w_l; e0 has one value per light (0: the
    // light does not shine there).
    struct PeakTarget {
        std::vector<double> e0;
        Field<double>* fluence = nullptr;
        Field<double>* flux = nullptr;
    };
    // Adds every light's forward_peak_mean to each target on the cells of box `cells` (inside
    // the targets' allocated boxes). Row by row: each light's row of means once for all targets,
    // the empty cells' two exponentials in vector lanes (exp_neg, as forward_peak_mean's; the
    // AVX2 clone rounds with FMA: test ForwardPeakRowsMatchTheCellMeans), then each target's
    // row summed over the lights and written once. On the default scene (9 lights, 3 bands, 1
    // rank) diffusion's bands step took 0.091 s against 0.134 s light by light over the bands'
    // fields with libm's exp (medians of 5). rho and tau_rho with their ghost layers. Not
    // collective.
    void add_forward_peak(const Decomposition& d, const Field<double>& rho, double sigma_t, double sigma_scaled,
                          double h, const Box& cells, const std::vector<PeakTarget>& targets) const;
    // Reduced-incident fluence ∫ I_ri dw = Σ E0 T (W/m²) in band b at cell (i, j, k).
    double fluence_reduced(const Medium& m, int b, int i, int j, int k) const;

private:
    // forward_peak_mean of the cells i0 <= i < i1 of row (j, k) into out[0 .. i1 - i0).
    void forward_peak_row(const Decomposition& d, const Field<double>& rho, int light, double sigma_t,
                          double sigma_scaled, double h, int i0, int i1, int j, int k, double* out) const;
    // forward_peak_mean in a cell with density lit by the light (tau_rho > 0).
    double forward_peak_in_medium(const Decomposition& d, const Field<double>& rho, int light, double sigma_t,
                                  double sigma_scaled, double h, int i, int j, int k) const;
    // What transmittance_mean reads around a cell, once for any sigma_t: tau_rho at the centre,
    // its gradient across the cell (density / metre), and tau_rho beyond each face the light
    // enters by with no medium beyond it (0 at the domain's face; -1: medium there, parallel
    // light, or an empty cell).
    struct CellProfile {
        Vec3 w, gradient;
        double tau = 0.0, rho = 0.0, h = 0.0;
        std::array<double, 3> tau_in{-1.0, -1.0, -1.0};
        double mean(double sigma_t) const;  // the cell's mean of T = e^{-sigma_t tau_rho}
        // Its parts: the linear profile's mean; the mean of the light entering by the faces with
        // nothing beyond them (0 where it cannot exceed `above`); the bound min(1, Σ|w_a| / (kappa h)).
        double profile_mean(double sigma_t) const;
        double face_floor(double sigma_t, double above) const;
        double bound(double sigma_t) const;
    };
    CellProfile profile(const Decomposition& d, const Field<double>& rho, int light, double h, int i, int j,
                        int k) const;
    // tau_rho beyond the face on axis a by which the light enters (transmittance_beyond's, before the
    // exp). profile() answers the same from the reads it makes anyway (CellProfile::tau_in).
    double tau_beyond(const Decomposition& d, const Field<double>& rho, int light, int i, int j, int k, int a) const;
};

// What FirstScatterMeans found per light: the power (per unit E0, W per W/m²) that the cells'
// unscaled means of T take, the most the beam loses in the domain, and the factor applied.
struct FirstScatterBound {
    struct Light {
        std::string name;
        double taken = 0.0, lost = 0.0, scale = 1.0;
    };
    std::vector<Light> lights;  // one per light of the LightTransport, in its order
    // Every cut light is recorded in report.values()["first_scatter_bound"][band][light name] as
    // {taken, lost}; if speak, a warning for each cut by more than 1%, naming `band`.
    void report(const std::string& band, Report& report, bool speak) const;
};

// The cell means of T that a model's first-scatter source integrates, at one sigma_t: each
// cell's transmittance_mean, scaled per light where all cells together would take more than the
// beam loses in the domain. Per unit E0 the beam brings h² |w_a| through every cell of each
// non-periodic face it enters by and takes out h² |w_a| T through the faces it leaves by; the
// loss is estimated from above (T of the darkest of each leaving cell and its neighbours in the
// face, 0 at density), so that a correct source is not cut. The cells take Σ kappa <T> h³. The
// linear profile of transmittance_mean over-counts where tau bends inside cells on a scale it
// cannot see: under a grazing sun over periodic x/y (w_z = -0.016) the cells took 1.9x the
// beam. Holds references to lt, d and rho, which must outlive it. Collective construction.
//
// The pass that sums the means keeps them (one double per used light and cell of the bounding
// box of the rank's cells with density, for at most kMaxKeptLights used lights), so that the
// model's own pass over the cells reads them instead of computing each a second time: on the
// bench cumulus at 128³ the second computation was 0.027 s of diffusion's 0.079 s sources step.
class FirstScatterMeans {
public:
    static constexpr int kMaxKeptLights = 16;
    // lit[l] false: light l is not used (no pass over the cells; scale 1); empty: all are.
    FirstScatterMeans(const LightTransport& lt, const Decomposition& d, const Field<double>& rho, double sigma_t,
                      double h, const std::vector<bool>& lit = {});
    // kappa <T> h³ of cell (i, j, k) is sigma_t rho h³ times this.
    double operator()(int light, int i, int j, int k) const {
        const int slot = kept_slot_.empty() ? -1 : kept_slot_[static_cast<size_t>(light)];
        if (slot >= 0 && kept_.owned().contains(i, j, k) && rho_(i, j, k) > 0.0)
            return scale(light) * kept_(i, j, k, slot);
        return scale(light) * lt_.transmittance_mean(d_, rho_, light, sigma_t_, h_, i, j, k);
    }
    double scale(int light) const { return bound_.lights[static_cast<size_t>(light)].scale; }
    double taken(int light) const { return bound_.lights[static_cast<size_t>(light)].taken; }
    double lost(int light) const { return bound_.lights[static_cast<size_t>(light)].lost; }
    const FirstScatterBound& bound() const { return bound_; }
    // bound().report with rank 0 speaking.
    void report(const std::string& band, Report& report) const { bound_.report(band, report, d_.rank() == 0); }

private:
    const LightTransport& lt_;
    const Decomposition& d_;
    const Field<double>& rho_;
    double sigma_t_, h_;
    FirstScatterBound bound_;
    // The unscaled means of the cells with density, light l's in component kept_slot_[l] (-1: not
    // kept); empty when more than kMaxKeptLights lights are used.
    Field<double> kept_;
    std::vector<int> kept_slot_;
};

struct DiffuseSolution {
    std::vector<Field<double>> fluence;         // per band, 4πU, W/m², owned + 1 ghost
    std::vector<Field<double>> flux;            // per band, F (3 components), or empty
    std::vector<Field<double>> fluence_stderr;  // per band standard error (Monte Carlo), or empty
    // The angular shape the renderer gives the radiance between fluence and flux: the P1
    // radiance for the diffusion model (its own ansatz), the realizable closure for the moments
    // of a transport solution (the default).
    RadianceClosure closure = RadianceClosure::realizable;
};

// fluence_diffuse below -share of its band's largest value (the exact answer is never negative;
// a truncated phase function or a signed correction can make a model's so): per such band its
// name, the cells below, the least and the largest value. Collective.
struct NegativeFluence {
    std::string band;
    std::int64_t cells = 0;
    double min = 0.0, max = 0.0;
    nlohmann::json json() const { return {{"cells", cells}, {"min", min}, {"max", max}}; }
};
inline constexpr double kNegativeFluenceShare = 1e-3;
std::vector<NegativeFluence> find_negative_fluence(const Decomposition& d, const std::vector<BandOptics>& bands,
                                                   const DiffuseSolution& out,
                                                   double share = kNegativeFluenceShare);

// The largest density of any cell, over all ranks. Collective.
double max_density(const Decomposition& d, const Medium& m);
// The largest optical depth of a cell, max over cells and bands of rho sigma_t h. Collective.
double max_cell_optical_depth(const Decomposition& d, const Medium& m);

// Where a cell is more than `limit` optical depths thick, rank 0 warns once:
// "model <model>: cells up to <depth> optical depths thick: <consequence>". Collective.
void warn_if_cells_thick(const Decomposition& d, const Medium& m, const std::string& model, double limit,
                         const std::string& consequence);

struct SolveContext {
    const Scene& scene;
    const Decomposition& decomp;
    const Medium& medium;
    const LightTransport& light;
    Report& report;
};

class ScatteringModel {
public:
    virtual ~ScatteringModel() = default;
    virtual std::string name() const = 0;
    // Effective options, echoed by rank 0 and stored in the HDF5 output.
    virtual nlohmann::json options() const { return nlohmann::json::object(); }
    // Collective over ctx.decomp.comm(). Fills out.fluence (and flux/stderr where it can).
    // Throws Error (on every rank) when it cannot produce a trustworthy result.
    virtual void solve(const SolveContext& ctx, DiffuseSolution& out) = 0;
    // Models that render the camera image themselves (Monte Carlo path tracing) return true;
    // the pipeline then calls render() (collective; image on rank 0) instead of the ray caster.
    virtual bool renders_image() const { return false; }
    virtual Image render(const SolveContext& /*ctx*/) { return {}; }
    // Bytes this rank's solve will hold at its peak beyond the light pass and the renderer, for
    // the memory check that `info` and `run` make before anything is allocated (src/cmd/memory.h).
    // nlights: the scene's light terms (sun + sky bins). Estimates calibrated against measured
    // peaks are fine; 0 when the model needs nothing per cell.
    virtual double memory_bytes(const Scene& /*s*/, const Decomposition& /*d*/, int /*nlights*/) const { return 0.0; }
    // Collective. Throws the Error that solve() would throw for this scene and medium for a
    // reason known before the light pass (limits, unsupported combinations), so that `run`
    // fails before its costly phases and `info` fails on the same scenes.
    virtual void check(const Scene& /*s*/, const Decomposition& /*d*/, const Medium& /*m*/) const {}
    // The part of check() that depends on the decomposition alone (process grid, periodic axes
    // split over ranks). No communication: `nimbus info --ranks N` calls it on the planned
    // decomposition of N ranks, which has no communicator. check() makes it too.
    virtual void check_layout(const Decomposition& /*d*/) const {}
    // The part of check() that needs the scene and the decomposition but not the density (limits
    // set by the grid's size). No communication, like check_layout: `nimbus info --ranks N` makes
    // it on the plan when the density is too big to build on its one process. check() makes it too.
    virtual void check_scene(const Scene& /*s*/, const Decomposition& /*d*/) const {}
};

// Zero-initialized fluence fields for every band on d's local box (+1 ghost).
DiffuseSolution zero_solution(const Decomposition& d, int nbands);

// Options (src/model/options.h) as the JSON object a model's options() returns: one entry per
// key of their for_each_option.
template <class Options>
nlohmann::json options_json(const Options& o) {
    nlohmann::json j = nlohmann::json::object();
    for_each_option(o, [&](const char* key, const auto& value) { j[key] = value; });
    return j;
}

}  // namespace nimbus
