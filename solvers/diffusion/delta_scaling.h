// Delta-Eddington scaling of the band optics for the P1 solve (pure, no MPI).
//
// A Henyey-Greenstein phase function with g = 0.85 puts most scattered light into a narrow
// forward lobe. P1 represents the diffuse radiance as U + (3/4π) F·w; when that radiance is
// dominated by once-scattered, still nearly collimated light, the first-scatter flux
// G = Q1/kappa_tr exceeds what a non-negative linear-in-w radiance can carry, and U goes
// negative where the sun enters the cloud (README, "Negative fluence"). The delta-Eddington
// approximation (Joseph, Wiscombe & Weinman 1976, J. Atmos. Sci. 33, 2452) replaces
//   p(w·w') = f δ(w - w') + (1 - f) p'(w·w'),   f = g², g' = (g - f)/(1 - f) = g/(1 + g),
// i.e. the fraction f of scattering is treated as no scattering at all (the light keeps its
// direction). The RTE is unchanged under
//   sigma_t' = sigma_t (1 - a f),   a' = a (1 - f)/(1 - a f),
// and the light that travelled on in the forward peak stays in the reduced-incident part:
//   T'(x) = exp(-sigma_t' tau_rho(x)) >= T(x).
// The P1 operator is invariant: sigma_t'(1 - a'g') = sigma_t(1 - a g) (kappa_tr) and
// sigma_t'(1 - a') = sigma_t(1 - a) (sigma_a); only the sources change:
//   Q0' = (1/4π) rho sigma_t a (1 - f) E0 T',   Q1' = g' Q0' w_sun.
// The diffuse fluence (DESIGN §1: everything but the unscattered sun) is then
//   ∫ I_d dw = 4π U' + E0 (T' - T)            (summed over light terms)
// and the diffuse flux F = F' + E0 (T' - T) w_sun.
#pragma once

namespace nimbus::diffusion {

struct DeltaScaledOptics {
    double f = 0.0;        // forward-peak fraction, g²
    double sigma_t = 0.0;  // sigma_t (1 - a f), 1/m per unit density
    double albedo = 0.0;   // a (1 - f)/(1 - a f); 0 when a f = 1 (all scattering is forward)
    double g = 0.0;        // g/(1 + g)
};

// enabled = false, or g <= 0 (no forward peak to truncate), returns the optics unchanged
// (f = 0): plain P1.
inline DeltaScaledOptics delta_scale(double sigma_t, double albedo, double g, bool enabled) {
    DeltaScaledOptics o;
    enabled = enabled && g > 0.0;
    o.f = enabled ? g * g : 0.0;
    o.sigma_t = sigma_t * (1.0 - albedo * o.f);
    const double den = 1.0 - albedo * o.f;
    o.albedo = den > 0.0 ? albedo * (1.0 - o.f) / den : 0.0;
    o.g = enabled ? g / (1.0 + g) : g;
    return o;
}

}  // namespace nimbus::diffusion
