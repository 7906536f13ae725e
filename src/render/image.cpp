#include "src/render/image.h"

#include <algorithm>
#include <cctype>

namespace nimbus {

std::array<int, 3> rgb_band_of_channel(const std::vector<std::string>& band_names) {
    std::array<int, 3> band{0, 1, 2};
    if (band_names.size() != 3) return {0, 0, 0};
    std::vector<std::string> lower = band_names;
    for (std::string& n : lower)
        std::transform(n.begin(), n.end(), n.begin(), [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
    for (const std::array<const char*, 3>& rgb : {std::array<const char*, 3>{"r", "g", "b"},
                                                  std::array<const char*, 3>{"red", "green", "blue"}}) {
        std::array<int, 3> found{-1, -1, -1};
        for (int c = 0; c < 3; ++c) {
            const auto it = std::find(lower.begin(), lower.end(), rgb[static_cast<size_t>(c)]);
            if (it != lower.end()) found[static_cast<size_t>(c)] = static_cast<int>(it - lower.begin());
        }
        if (std::none_of(found.begin(), found.end(), [](int b) { return b < 0; })) return found;
    }
    return band;
}

void order_channels_by_band_name(Image& img, const std::vector<std::string>& band_names) {
    const std::array<int, 3> band = rgb_band_of_channel(band_names);
    if (img.empty() || band_names.size() != 3 || band == std::array<int, 3>{0, 1, 2}) return;
    auto permute = [&](std::vector<float>& v, size_t stride) {
        for (size_t p = 0; p + 3 <= v.size(); p += stride) {
            const float in[3] = {v[p], v[p + 1], v[p + 2]};
            for (size_t c = 0; c < 3; ++c) v[p + c] = in[static_cast<size_t>(band[c])];
        }
    };
    permute(img.rgba, 4);
    permute(img.stderr_rgb, 3);
}

}  // namespace nimbus
