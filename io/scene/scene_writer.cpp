// Scene -> TOML text with every field written (the effective scene of a run), in the layout of
// scenes/default.toml. load_scene_string() reads it back to an equal Scene: floats are written
// with the shortest text that reads back bit for bit, per-band values of size 1 as a number,
// lengths in the scene's unit (a unit whose scale is not the named one's becomes "custom").
// With TomlComments::meanings every key and table also gets its meaning (io/scene/key_docs.h)
// as a comment, the first time its path is written: the same lines, the same Scene read back.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "io/scene/key_docs.h"
#include "io/scene/scene_toml.h"
#include "io/scene/toml_reader.h"

namespace nimbus {
namespace {

std::string num(double x) {
    if (std::isnan(x)) return "nan";
    if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
    std::string s = fmt::format("{}", x);  // shortest round-trip representation
    if (s.find_first_of(".e") == std::string::npos) s += ".0";
    return s;
}

std::string str(const std::string& s) { return scene_io::toml_quoted(s); }

const char* boolean(bool b) { return b ? "true" : "false"; }

template <class T, class F>
std::string list(const T& values, F&& fmt_one) {
    std::string s = "[";
    bool first = true;
    for (const auto& v : values) {
        s += (first ? "" : ", ") + fmt_one(v);
        first = false;
    }
    return s + "]";
}

std::string nums(const std::array<double, 3>& a) { return list(a, num); }
std::string vec(const Vec3& v) { return nums({v.x, v.y, v.z}); }
std::string per_band(const std::vector<double>& v) { return v.size() == 1 ? num(v[0]) : list(v, num); }

// One model option's value, in the form of the rest of the file.
std::string option_value(int v) { return std::to_string(v); }
std::string option_value(std::int64_t v) { return std::to_string(v); }
std::string option_value(std::uint64_t v) { return std::to_string(v); }
std::string option_value(double v) { return num(v); }
std::string option_value(bool v) { return boolean(v); }
std::string option_value(const std::string& v) { return str(v); }
std::string option_value(const std::vector<std::string>& v) { return list(v, str); }

// Display columns of UTF-8 text: one per code point (the meanings hold no wide characters).
size_t columns(std::string_view s) {
    return static_cast<size_t>(std::count_if(
        s.begin(), s.end(), [](char c) { return (static_cast<unsigned char>(c) & 0xC0) != 0x80; }));
}

// text broken at spaces into lines of at most `width` columns (a longer word keeps its own line).
std::vector<std::string> wrap(std::string_view text, size_t width) {
    std::vector<std::string> lines;
    std::string line;
    for (size_t pos = 0; pos < text.size();) {
        const size_t end = std::min(text.find(' ', pos), text.size());
        const std::string_view word = text.substr(pos, end - pos);
        if (!line.empty() && columns(line) + 1 + columns(word) > width) {
            lines.push_back(line);
            line.clear();
        }
        if (!line.empty()) line += ' ';
        line += word;
        pos = end + 1;
    }
    if (!line.empty()) lines.push_back(line);
    return lines;
}

// text in as few lines of at most `width` columns as wrap() gives, as even as they go (a
// meaning of two lines never leaves one word on the second).
std::vector<std::string> wrap_even(std::string_view text, size_t width) {
    std::vector<std::string> lines = wrap(text, width);
    for (size_t w = width - 1; w > 0; --w) {
        std::vector<std::string> narrower = wrap(text, w);
        if (narrower.size() > lines.size()) break;
        lines = std::move(narrower);
    }
    return lines;
}

// The lines of the file, table by table. With meanings: a table's meaning on the lines above its
// header; a key's after its value from column kCommentColumn on, or on the lines above it when
// "key = value" reaches that column; comments wrapped at kWidth columns.
class TomlEmitter {
public:
    explicit TomlEmitter(TomlComments comments) : meanings_(comments == TomlComments::meanings) {}

    void comment(const std::string& text) { out_ << "# " << text << "\n"; }
    // [path]; a top-level table after a blank line (with meanings, every table).
    void table(const std::string& path) { header(path, "[" + path + "]"); }
    // [[path]], one per element of the list.
    void array_table(const std::string& path) { header(path, "[[" + path + "]]"); }

    void key(const std::string& key, const std::string& value) {
        const std::string line = key + " = " + value;
        const std::string_view m = meaning(table_.empty() ? key : table_ + "." + key);
        if (m.empty()) {
            out_ << line << "\n";
        } else if (columns(line) + 2 <= kCommentColumn) {
            const std::vector<std::string> lines = wrap_even(m, kWidth - kCommentColumn - 2);
            for (size_t i = 0; i < lines.size(); ++i) {
                const size_t used = i == 0 ? columns(line) : 0;
                out_ << (i == 0 ? line : "") << std::string(kCommentColumn - used, ' ') << "# "
                     << lines[i] << "\n";
            }
        } else {
            above(m);
            out_ << line << "\n";
        }
    }

    std::string text() const { return out_.str(); }

private:
    static constexpr size_t kCommentColumn = 33, kWidth = 100;

    void header(const std::string& path, const std::string& line) {
        if (meanings_ || path.find('.') == std::string::npos) out_ << "\n";
        above(meaning(path));
        out_ << line << "\n";
        table_ = path;
    }
    void above(std::string_view meaning) {
        for (const std::string& l : wrap_even(meaning, kWidth - 2)) out_ << "# " << l << "\n";
    }
    // The meaning to write for a path: only with meanings, and only the first time (the later
    // tables of a list repeat no comment).
    std::string_view meaning(const std::string& path) {
        if (!meanings_ || !documented_.insert(path).second) return {};
        return scene_key_meaning(path);
    }

    bool meanings_;
    std::ostringstream out_;
    std::string table_;               // the current table's path, "" before the first
    std::set<std::string> documented_;
};

// [model.<name>]: every key of the options' for_each_option (src/model/options.h), in order.
template <class Options>
void write_options(TomlEmitter& w, const std::string& name, const Options& opts) {
    w.table("model." + name);
    for_each_option(opts,
                    [&](const char* key, const auto& value) { w.key(key, option_value(value)); });
}

// The unit name to write: a named unit only when its scale is exactly the named one's.
bool named_unit(const GridSpec& g) {
    return (g.unit == "m" && g.unit_scale == 1.0) || (g.unit == "km" && g.unit_scale == 1000.0) ||
           (g.unit == "cm" && g.unit_scale == 0.01) || (g.unit == "mm" && g.unit_scale == 0.001);
}

// Text that can stand in a TOML comment: tab, printable ASCII and well-formed UTF-8 (no overlong
// form, surrogate or code point beyond U+10FFFF, as toml11 checks); any other byte becomes '?' (a
// scene file's path may hold a newline or a byte that is not UTF-8, and the stored scene could
// not be read back: a QA finding).
std::string comment_safe(const std::string& text) {
    std::string out;
    auto at = [&](size_t i) { return i < text.size() ? static_cast<unsigned char>(text[i]) : 0u; };
    for (size_t i = 0; i < text.size();) {
        const unsigned c = at(i);
        size_t n = 0;
        unsigned lo = 0x80, hi = 0xBF;  // the second byte's range
        if (c == 0x09 || (c >= 0x20 && c < 0x7F)) n = 1;
        else if (c >= 0xC2 && c <= 0xDF) n = 2;
        else if (c >= 0xE0 && c <= 0xEF) n = 3, lo = c == 0xE0 ? 0xA0 : 0x80, hi = c == 0xED ? 0x9F : 0xBF;
        else if (c >= 0xF0 && c <= 0xF4) n = 4, lo = c == 0xF0 ? 0x90 : 0x80, hi = c == 0xF4 ? 0x8F : 0xBF;
        bool ok = n > 0 && i + n <= text.size() && (n == 1 || (at(i + 1) >= lo && at(i + 1) <= hi));
        for (size_t k = 2; ok && k < n; ++k) ok = at(i + k) >= 0x80 && at(i + k) <= 0xBF;
        if (ok) {
            out.append(text, i, n);
            i += n;
        } else {
            out += '?';
            ++i;
        }
    }
    return out;
}

}  // namespace

std::string scene_to_toml(const Scene& s, TomlComments comments) {
    TomlEmitter w(comments);
    w.comment(fmt::format("nimbus scene: every setting of the run (written by nimbus; source: {})",
                          comment_safe(s.source)));
    w.key("title", str(s.title));

    const GridSpec& g = s.grid;
    w.table("grid");
    w.key("n", list(g.n, [](int v) { return std::to_string(v); }));
    w.key("cell_size", num(g.cell_size));
    if (named_unit(g)) {
        w.key("unit", str(g.unit));
    } else {
        w.key("unit", str("custom"));
        w.key("unit_scale", num(g.unit_scale));
    }
    w.key("process_grid", list(g.process_grid, [](int v) { return std::to_string(v); }));
    w.key("periodic", list(g.periodic, [](bool v) { return std::string(boolean(v)); }));

    const MediumSpec& m = s.medium;
    w.table("medium");
    w.key("kind", str(to_string(m.kind)));
    w.key("density", num(m.density));
    w.key("noise_amplitude", num(m.noise_amplitude));
    w.key("noise_scale", num(m.noise_scale));
    w.key("noise_octaves", std::to_string(m.noise_octaves));
    w.key("seed", std::to_string(m.seed));
    w.key("box_lo", nums(m.box_lo));
    w.key("box_hi", nums(m.box_hi));
    w.key("sphere_center", nums(m.sphere_center));
    w.key("sphere_radius", num(m.sphere_radius));
    if (!m.file.empty()) w.key("file", str(m.file));
    w.key("dataset", str(m.dataset));
    for (const Ellipsoid& e : m.ellipsoids) {
        w.array_table("medium.ellipsoid");
        w.key("center", nums(e.center));
        w.key("radii", nums(e.radii));
        w.key("density", num(e.density));
    }

    for (const BandOptics& b : s.bands) {
        w.array_table("optics");
        w.key("name", str(b.name));
        w.key("sigma_t", num(b.sigma_t));
        w.key("albedo", num(b.albedo));
        w.key("g", num(b.g));
    }

    w.table("sun");
    w.key("enabled", boolean(s.sun.enabled));
    w.key("direction", vec(s.sun.direction));
    w.key("irradiance", per_band(s.sun.irradiance));

    w.table("sky");
    w.key("radiance", per_band(s.sky.radiance));
    w.key("directions", std::to_string(s.sky.directions));

    for (const SourceSpec& src : s.sources) {
        w.array_table("sources");
        w.key("lo", nums(src.lo));
        w.key("hi", nums(src.hi));
        w.key("power", per_band(src.power));
    }

    w.table("light");
    w.key("method", str(to_string(s.light.method)));

    const CameraSpec& c = s.camera;
    w.table("camera");
    w.key("position", vec(c.position));
    w.key("look_at", vec(c.look_at));
    w.key("up", vec(c.up));
    w.key("fov", num(c.fov_deg));
    w.key("resolution", fmt::format("[{}, {}]", c.width, c.height));
    w.key("units", str(c.domain_units ? "domain" : "world"));

    const BackgroundSpec& bg = s.background;
    w.table("background");
    w.key("kind", str(bg.kind == BackgroundSpec::Kind::ground ? "ground" : "color"));
    w.key("color", per_band(bg.color));
    w.key("ground_albedo", num(bg.ground_albedo));
    w.key("ground_color", per_band(bg.ground_color));

    const RenderSpec& r = s.render;
    w.table("render");
    w.key("mode", str(to_string(r.mode)));
    w.key("step", num(r.step));
    w.key("early_termination", num(r.early_termination));
    w.key("emission_color", per_band(r.emission_color));
    w.key("exposure", num(r.exposure));

    w.table("model");
    w.key("name", str(s.model.name));
    write_options(w, "montecarlo", s.model.montecarlo);
    write_options(w, "diffusion", s.model.diffusion);
    write_options(w, "dom", s.model.dom);
    write_options(w, "lpm", s.model.lpm);
    write_options(w, "psf", s.model.psf);

    w.table("output");
    w.key("dir", str(s.output.dir));
    w.key("name", str(s.output.name));
    w.key("hdf5", boolean(s.output.hdf5));
    w.key("image", boolean(s.output.image));
    return w.text();
}

}  // namespace nimbus
