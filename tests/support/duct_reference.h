// The stored Monte Carlo reference of the void duct (scenes/duct.toml), shared by the DOM and
// Monte Carlo emission tests: tests/data/duct_mc_reference.csv, written by
// jobs/duct/make_reference.sh, one line "region,i,j,k,mean,stderr" per detector cell
// (regions end, wall, source: see jobs/duct/extract_reference.py). Also the scene itself,
// loaded from the file with its raw density. Header-only; load is collective (density import).
#pragma once

#include <algorithm>
#include <array>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "io/scene/density_import.h"
#include "io/scene/scene_toml.h"
#include "src/model/model.h"

namespace nimbus::test {

struct RefCell {
    double mean = 0.0, se = 0.0;  // W/m², batch-means standard error
};
using DuctRegion = std::map<std::array<int, 3>, RefCell>;

// region name -> cells; empty if the file is missing.
inline std::map<std::string, DuctRegion> read_duct_reference() {
    std::ifstream in(std::string(NIMBUS_TEST_DATA_DIR) + "/duct_mc_reference.csv");
    std::map<std::string, DuctRegion> ref;
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#' || line.rfind("region", 0) == 0) continue;
        std::replace(line.begin(), line.end(), ',', ' ');
        std::istringstream s(line);
        std::string region;
        std::array<int, 3> c{};
        RefCell r;
        s >> region >> c[0] >> c[1] >> c[2] >> r.mean >> r.se;
        ref[region][c] = r;
    }
    return ref;
}

// scenes/duct.toml on comm: scene, decomposition (slabs), medium with the imported density.
struct DuctWorld {
    Scene scene;
    Decomposition d;
    Medium m;
    LightTransport light;  // no sun, no sky
    Report report;
    explicit DuctWorld(MPI_Comm comm)
        : scene(load_scene_file(std::string(NIMBUS_SOURCE_DIR) + "/scenes/duct.toml")),
          d(comm, scene.grid.n, {0, 0, 0}, {false, false, false}) {
        m = load_medium(scene, d);
    }
    SolveContext ctx() { return {scene, d, m, light, report}; }
};

}  // namespace nimbus::test
