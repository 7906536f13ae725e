// Directional light terms: the sun and the uniform sky, each a collimated beam of irradiance
// E0 (per band, W/m² on a plane normal to w) travelling along unit w (DESIGN §1). The sky
// is discretized into direction bins of equal solid angle over the upper hemisphere (rings of
// 4 symmetric bins when 4 divides their count, else a spiral: lights.cpp); a bin of solid angle
// Ω and radiance L becomes a beam of irradiance L Ω along its central direction.
#pragma once

#include <string>
#include <vector>

#include "src/core/vec3.h"
#include "src/scene/scene.h"

namespace nimbus {

struct DirectionalLight {
    std::string name;          // "sun", "sky[3]"
    Vec3 w;                    // unit travel direction
    std::vector<double> E0;    // per band, W/m²
};

// All light terms of a scene, sun first. Per-band values of size 1 are broadcast to all bands.
// A sky whose radiance is 0 in every band gives no terms.
std::vector<DirectionalLight> make_lights(const Scene& scene);

// v[b] if v has one entry per band, v[0] if it has one value.
inline double band_value(const std::vector<double>& v, int b) {
    return v.size() == 1 ? v[0] : v[static_cast<size_t>(b)];
}

}  // namespace nimbus
