// Image: linear RGBA radiance, row-major with the top row first, 4 floats per pixel.
// Colour bands map to RGB: one band (gray) -> r = g = b; three bands -> r, g, b in their order
// as the renderers make it, then by name for the files (rgb_band_of_channel).
// alpha = 1 - T, the opacity of the volume along the pixel's view ray.
#pragma once

#include <array>
#include <string>
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

// The band each channel R, G, B shows: three bands named r, g, b (or red, green, blue; any
// case) by their names, in whatever order the scene lists them; any other three in their order;
// one band (gray) in all three.
std::array<int, 3> rgb_band_of_channel(const std::vector<std::string>& band_names);

// Puts the channels of an image made in band order (channel c = band c, as the renderers make
// it) where rgb_band_of_channel says, with their standard errors. An empty image stays empty.
void order_channels_by_band_name(Image& img, const std::vector<std::string>& band_names);

}  // namespace nimbus
