// Every key and table scene_to_toml writes has a meaning in io/scene/key_docs.cpp, and every
// meaning there is of a key some scene writes (so a key cannot be added undocumented, nor a
// documented one removed silently); the text with meanings only adds comments, each meaning
// once, within 100 columns; and docs/scene_reference.toml is that text for the smallest scene
// file. Regenerate the reference with
//   NIMBUS_WRITE_SCENE_REFERENCE=1 build/tests/unit/io_scene/test_io_scene --gtest_filter='*Reference*'
#include "io/scene/key_docs.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "io/scene/scene_toml.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

// The smallest valid scene file: one band, by name (at least one is required).
const std::string kMinimal = "[[optics]]\nname = \"gray\"\n";

// One path of a written scene: a key, or a table's header ([table] or [[list]]).
struct Written {
    enum Kind { key, table, list } kind;
    std::string path;  // "grid.cell_size", "model.dom", "sources"
    std::string line;  // the line as written
};

// The keys and tables of scene_to_toml text in order, as dotted paths; comments skipped.
std::vector<Written> written(const std::string& toml) {
    std::vector<Written> out;
    std::istringstream in(toml);
    std::string line, table;
    while (std::getline(in, line)) {
        const auto first = line.find_first_not_of(' ');
        if (first == std::string::npos || line[first] == '#') continue;
        if (line.rfind("[[", 0) == 0) {
            table = line.substr(2, line.find("]]") - 2);
            out.push_back({Written::list, table, line});
        } else if (line.front() == '[') {
            table = line.substr(1, line.find(']') - 1);
            out.push_back({Written::table, table, line});
        } else {
            const std::string key = line.substr(0, line.find(" = "));
            out.push_back({Written::key, table.empty() ? key : table + "." + key, line});
        }
    }
    return out;
}

// A scene that writes every key: the minimal one plus what only some scenes have (a custom
// unit, a density file, a cumulus ellipsoid, a volume source).
Scene scene_with_every_key() {
    Scene s = load_scene_string(kMinimal, "minimal.toml");
    s.grid.unit = "custom";
    s.grid.unit_scale = 0.3048;
    s.medium.file = "/data/density.raw";
    s.medium.ellipsoids = {Ellipsoid{}};
    s.sources = {SourceSpec{{0.0, 0.0, 0.0}, {2.0, 2.0, 2.0}, {1.0}}};
    s.model.name = "dom";  // a model that supports [[sources]]
    return s;
}

std::vector<Scene> scenes() {
    return {load_scene_string(kMinimal, "minimal.toml"), default_scene(), scene_with_every_key()};
}

size_t columns(const std::string& s) {  // display columns: code points
    return static_cast<size_t>(std::count_if(
        s.begin(), s.end(), [](char c) { return (static_cast<unsigned char>(c) & 0xC0) != 0x80; }));
}

// text in as few lines of at most `width` columns as filling them gives, as even as they go.
std::vector<std::string> wrap_even(const std::string& text, size_t width) {
    const auto fill = [&](size_t w) {
        std::vector<std::string> lines;
        std::istringstream words(text);
        std::string word;
        while (words >> word) {
            if (lines.empty() || columns(lines.back()) + 1 + columns(word) > w) {
                lines.push_back(word);
            } else {
                lines.back() += " " + word;
            }
        }
        return lines;
    };
    std::vector<std::string> lines = fill(width);
    for (size_t w = width - 1; w > 0 && fill(w).size() == lines.size(); --w) lines = fill(w);
    return lines;
}

TEST(KeyDocs, EveryWrittenKeyAndTableHasAMeaning) {
    for (const Scene& s : scenes())
        for (const Written& w : written(scene_to_toml(s)))
            EXPECT_FALSE(scene_key_meaning(w.path).empty())
                << "'" << w.line << "' (" << w.path
                << ") has no meaning: add one to io/scene/key_docs.cpp";
}

TEST(KeyDocs, EveryMeaningIsOfAWrittenKey) {
    std::set<std::string> paths;
    for (const Scene& s : scenes())
        for (const Written& w : written(scene_to_toml(s))) paths.insert(w.path);
    std::set<std::string_view> seen;
    for (const KeyDoc& d : scene_key_docs()) {
        EXPECT_TRUE(paths.count(std::string(d.path)))
            << d.path << " is documented in io/scene/key_docs.cpp but no scene writes it";
        EXPECT_TRUE(seen.insert(d.path).second) << d.path << " is documented twice";
        EXPECT_FALSE(d.meaning.empty()) << d.path;
    }
    EXPECT_EQ(scene_key_meaning("grid.cell_size"), "cell edge length, in grid.unit (> 0; at least 1 nm in metres)");
    EXPECT_TRUE(scene_key_meaning("grid.no_such_key").empty());
}

// The text with meanings is the plain text plus comments: the same keys and tables in the same
// order, each line unchanged before its comment; it reads back to the same scene (every
// example scene: scene_load_test.cpp). Each meaning is written once, and every line with a
// comment fits 100 columns.
TEST(KeyDocs, MeaningsOnlyAddCommentsThatFit) {
    for (const Scene& s : scenes()) {
        const std::string plain = scene_to_toml(s),
                          commented = scene_to_toml(s, TomlComments::meanings);
        const std::vector<Written> a = written(plain), b = written(commented);
        ASSERT_EQ(a.size(), b.size());
        for (size_t i = 0; i < a.size(); ++i) {
            EXPECT_EQ(a[i].path, b[i].path);
            EXPECT_EQ(b[i].line.substr(0, a[i].line.size()), a[i].line);
            const std::string rest = b[i].line.substr(a[i].line.size());
            EXPECT_TRUE(rest.empty() || rest.find_first_not_of(' ') == rest.find("# "))
                << b[i].line;
        }
        // Past the first line, "source: ...".
        const auto body = [](const std::string& t) { return t.substr(t.find('\n')); };
        EXPECT_EQ(body(scene_to_toml(load_scene_string(commented, "<commented>"))), body(plain));

        // The comments, joined: every meaning of a written path; a list's (three [[optics]] in
        // the default scene) only at its first table.
        std::istringstream in(commented);
        std::string line, comments;
        while (std::getline(in, line)) {
            const auto hash = line.find("# ");
            if (hash == std::string::npos) continue;
            comments += line.substr(hash + 2) + " ";
            if (line.rfind("# nimbus scene:", 0) != 0) {
                EXPECT_LE(columns(line), 100u) << line;
            }
        }
        std::set<std::string> paths;
        for (const Written& w : a) paths.insert(w.path);
        for (const std::string& p : paths)
            EXPECT_NE(comments.find(scene_key_meaning(p)), std::string::npos)
                << p << ": " << scene_key_meaning(p);
        const std::string sigma_t(scene_key_meaning("optics.sigma_t"));
        EXPECT_EQ(comments.find(sigma_t, comments.find(sigma_t) + 1), std::string::npos);
    }
}

// docs/scene_reference.toml: the smallest scene file's every key with its meaning and the value
// it takes when a scene file leaves it out; the keys only some scenes write listed in its header.
TEST(KeyDocs, ReferenceFileListsEveryKeyAndItsMeaning) {
    const std::string path = std::string(NIMBUS_SOURCE_DIR) + "/docs/scene_reference.toml";
    const Scene minimal = load_scene_string(kMinimal, "minimal.toml");
    std::string header =
        "# Every scene key: what it means (unit, allowed values) and the value it takes when a\n"
        "# scene file leaves it out, which is what nimbus loads from the smallest valid file (one\n"
        "# [[optics]] table with only a name: at least one band is required), written back with\n"
        "# each key's meaning (io/scene/key_docs.cpp). The built-in default scene,\n"
        "# scenes/default.toml (a cumulus, Monte Carlo, exact light pass, sun and sky), sets many\n"
        "# of them differently. Each run stores its own effective scene in this form, without the\n"
        "# comments, in the HDF5 file (/scene, attribute toml).\n"
        "# Lengths: cell_size and [[sources]] lo/hi in grid.unit; positions and sizes in [medium]\n"
        "# in grid fractions (0 to 1 along each axis); the camera's in fractions of the domain or\n"
        "# in metres. \"Per band\": one value for all bands, or one per [[optics]] table.\n"
        "#\n"
        "# Written only in some scenes (lists are empty here; two keys need another value):\n";
    std::set<std::string> in_minimal;
    for (const Written& w : written(scene_to_toml(minimal))) in_minimal.insert(w.path);
    for (const Written& w : written(scene_to_toml(scene_with_every_key()))) {
        if (in_minimal.count(w.path)) continue;
        in_minimal.insert(w.path);  // a list's later tables: once
        const std::string name =
            w.kind == Written::list ? "[[" + w.path + "]]"
            : w.path.rfind("sources.", 0) == 0 || w.path.rfind("medium.ellipsoid.", 0) == 0
                ? "  " + w.path.substr(w.path.rfind('.') + 1)
                : w.path;
        // The meaning from column 26, wrapped at 100 into even lines.
        const std::vector<std::string> lines =
            wrap_even(std::string(scene_key_meaning(w.path)), 74);
        for (size_t i = 0; i < lines.size(); ++i)
            header += (i == 0 ? "#   " + name : "#") +
                      std::string(26 - (i == 0 ? 4 + name.size() : 1), ' ') + lines[i] + "\n";
    }
    header += "#\n# Generated by tests/unit/io_scene/key_docs_test.cpp.\n";
    const std::string want = header + scene_to_toml(minimal, TomlComments::meanings);
    if (std::getenv("NIMBUS_WRITE_SCENE_REFERENCE") && test::world_rank() == 0)
        std::ofstream(path) << want;
    std::ifstream in(path);
    ASSERT_TRUE(in.good()) << path;
    const std::string have((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(have, want) << "regenerate docs/scene_reference.toml (see the top of this file)";
    // It loads back to the same scene.
    auto body = [](const std::string& toml) {
        return toml.substr(toml.find('\n'));
    };  // past "source: ..."
    EXPECT_EQ(body(scene_to_toml(load_scene_string(have, path))), body(scene_to_toml(minimal)));
}

}  // namespace
}  // namespace nimbus
