// The diffuse radiance's angular shape rebuilt from its first two moments, and the in-scatter
// it gives: what the ray caster needs from a model that solved for the fluence Φ = ∫ I_d dw =
// 4πU and the flux F = ∫ I_d w dw only (src/render/source_kernel.h). Pure functions.
//
// With the phase function HG(g) (DESIGN §1), f = |F|/Φ (the radiance's mean cosine about F̂,
// 0..1 for a radiance) and μ = F̂·w, the in-scatter ∫ p(w·w') I_d(w') dw' of a shape with
// Legendre coefficients a_l (a_0 = 1, a_1 = f) is U Σ (2l+1) a_l g^l P_l(μ) (Funk-Hecke):
//
//   p1          the P1 radiance U (1 + 3 f μ), the diffusion model's own ansatz:
//               U + (3g/4π) F·w. It is negative opposite F once f > 1/3; its F term is then
//               scaled to the bound 3|g||F|/4π = U so that the in-scatter stays >= 0.
//   realizable  for the moments of a transport solution (dom, lpm, Monte Carlo), where f
//               reaches 0.75 in a thin forward-scattering cloud and the P1 shape, clamped,
//               rendered it 2× too bright seen side-on. P1 while it is a radiance (f <= 1/3: the
//               diffusive regime, where the true radiance is P1 to leading order); above, the
//               mix with weights 1 - s and s, s = (3f - 1)/2, of two non-negative shapes of
//               mean cosine f:
//                 B  the P1 radiance at its bound, U(1 + μ), under a beam along F̂, with weights
//                    1 - s and s (mean cosine (1 - s)/3 + s = f): (1 - s)(1 + g μ) + s 4π p(μ; g)
//                 H  the Henyey-Greenstein lobe of mean cosine f, 4π U p(μ; f), whose
//                    coefficients f^l times the phase's g^l make the lobe HG(g f): 4π p(μ; g f)
//               so  J/U = (1 - s) [(1 - s)(1 + g μ) + s 4π p(μ; g)] + s 4π p(μ; g f).
//               Continuous in f (s = 0 at f = 1/3 is P1 at its bound), a radiance for every f,
//               the beam's single scatter 4π p(μ; g) at f = 1, and its mean over directions U.
//               B alone was too dark seen against the beam and too bright along it, H alone
//               too dark across a bright cloud's diffusive interior; the mix was within 0.17-0.35
//               of the path tracer's image on a thin g = 0.85 sphere where the P1 shape was
//               0.38-1.12 off, and as close as P1 on thick clouds (the table: README, "Scene
//               files").
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

#include "src/core/vec3.h"
#include "src/physics/phase.h"

namespace nimbus {

enum class RadianceClosure { p1, realizable };

// ∫ p(w·w') I_d(w') dw' toward w_out (unit) for the shape `closure` of fluence Φ and flux F.
// Where Φ <= 0 (a model's negative fluence) or F = 0 it is the isotropic U = Φ/4π.
inline double closure_inscatter(RadianceClosure closure, double fluence, double g, const Vec3& F,
                                const Vec3& w_out) {
    constexpr double inv_4pi = 0.25 / std::numbers::pi, four_pi = 4.0 * std::numbers::pi;
    const double U = fluence * inv_4pi, Fn = norm(F);
    if (closure == RadianceClosure::p1) {
        const double amplitude = 3.0 * std::abs(g) * inv_4pi * Fn, limit = std::max(U, 0.0);
        const double scale = amplitude > limit ? limit / amplitude : 1.0;
        return U + scale * 3.0 * g * inv_4pi * dot(F, w_out);
    }
    if (!(fluence > 0.0) || Fn == 0.0) return U;
    const double f = std::min(Fn / fluence, 1.0), mu = dot(F, w_out) / Fn;
    if (f <= 1.0 / 3.0) return U * (1.0 + 3.0 * g * f * mu);
    const double s = 0.5 * (3.0 * f - 1.0);
    const double beam_over_floor = (1.0 - s) * (1.0 + g * mu) + s * four_pi * hg_phase(g, mu);
    const double lobe = four_pi * hg_phase(g * f, mu);
    return U * ((1.0 - s) * beam_over_floor + s * lobe);
}

}  // namespace nimbus
