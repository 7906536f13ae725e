// Image: linear RGBA radiance, row-major with the top row first, 4 floats per pixel.
// Colour bands map to RGB: one band (gray) -> r = g = b; three bands -> r, g, b.
// alpha = 1 - T, the opacity of the volume along the pixel's view ray.
#pragma once

#include <vector>

namespace nimbus {

struct Image {
    int width = 0, height = 0;
    std::vector<float> rgba;    // width * height * 4
    std::vector<float> stderr_rgb;  // optional per-pixel standard error (width * height * 3), Monte Carlo

    Image() = default;
    Image(int w, int h) : width(w), height(h), rgba(static_cast<size_t>(w) * h * 4, 0.0f) {}
    float* pixel(int x, int y) { return &rgba[(static_cast<size_t>(y) * width + x) * 4]; }
    const float* pixel(int x, int y) const { return &rgba[(static_cast<size_t>(y) * width + x) * 4]; }
    bool empty() const { return rgba.empty(); }
};

}  // namespace nimbus
