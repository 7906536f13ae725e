// sRGB transfer function (IEC 61966-2-1), a pure kernel used by the PNG preview:
//   s = 12.92 v                      for v <= 0.0031308
//   s = 1.055 v^(1/2.4) - 0.055      otherwise,
// with v the linear value clamped to [0, 1]; 8-bit code = round(255 s).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace nimbus {

inline double srgb_encode(double v) {
    v = std::clamp(v, 0.0, 1.0);
    return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

// NaN maps to 0 (std::clamp would pass it through).
inline std::uint8_t srgb8(double v) {
    if (!(v > 0.0)) return 0;
    return static_cast<std::uint8_t>(std::lround(255.0 * srgb_encode(v)));
}

}  // namespace nimbus
