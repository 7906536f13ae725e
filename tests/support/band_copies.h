// Test helper for the band-sharing tests (src/physics/band_groups.h): copies of one band's optics
// named "band<b>" for each b of a list, so that a run of bands {0, 1, 2} and a run of band {1}
// alone name the same band alike.
#pragma once

#include <string>
#include <vector>

#include "src/scene/scene.h"

namespace nimbus::test {

inline std::vector<BandOptics> band_copies(const BandOptics& optics, const std::vector<int>& bands) {
    std::vector<BandOptics> out;
    for (int b : bands) {
        BandOptics o = optics;
        o.name = "band" + std::to_string(b);
        out.push_back(o);
    }
    return out;
}

}  // namespace nimbus::test
