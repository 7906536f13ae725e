// OpenEXR and PNG writers/readers for nimbus::Image (see image_io.h). Not collective.
//
// EXR: scanline file, ZIP compression, FLOAT channels R, G, B, A (+ stderr.R/G/B when the image
// carries a Monte Carlo standard error), linear radiance W/(m² sr), bit-exact on read.
// PNG: 8-bit RGBA through libpng's simplified write API, which also writes the sRGB chunk;
// colour = srgb8(v * exposure) (io/output/srgb.h); opaque (alpha 255), because the colour
// already holds the background seen through the volume (the EXR keeps the volume's alpha).
// A failed write removes what it wrote; naming (temporaries, commit) is the caller's.
#include "io/output/image_io.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStdIO.h>
#include <png.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <vector>

#include "io/output/srgb.h"
#include "src/core/error.h"

namespace nimbus {

namespace fs = std::filesystem;

namespace {

constexpr const char* kRgbaNames[4] = {"R", "G", "B", "A"};
constexpr const char* kStderrNames[3] = {"stderr.R", "stderr.G", "stderr.B"};

void check_image(const std::string& path, const Image& img) {
    const size_t pixels = static_cast<size_t>(std::max(img.width, 0)) * std::max(img.height, 0);
    if (img.width <= 0 || img.height <= 0 || img.rgba.size() != pixels * 4)
        throw Error("cannot write image file '" + path + "': empty or inconsistent image");
    if (!img.stderr_rgb.empty() && img.stderr_rgb.size() != pixels * 3)
        throw Error("cannot write image file '" + path + "': stderr_rgb has the wrong size");
}

// Removes a partly written file and throws the write error.
[[noreturn]] void fail(const std::string& path, const std::string& why) {
    std::error_code ec;
    fs::remove(path, ec);
    throw Error("cannot write image file '" + path + "': " + why);
}

Imf::Slice float_slice(const float* base, size_t components, int width, float fill = 0.0f) {
    const size_t x_stride = components * sizeof(float);
    return Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(base)), x_stride,
                      x_stride * static_cast<size_t>(width), 1, 1, fill);
}

}  // namespace

void write_exr(const std::string& path, const Image& img) {
    check_image(path, img);
    // Our own stream: OpenEXR writes the offset table and closes its own stream in
    // destructors, which swallow errors (a disk filling up at the last block).
    std::ofstream os(path, std::ios::binary | std::ios::trunc);
    if (!os) fail(path, std::strerror(errno));
    try {
        Imf::Header header(img.width, img.height);
        header.compression() = Imf::ZIP_COMPRESSION;
        Imf::FrameBuffer fb;
        for (int c = 0; c < 4; ++c) {
            header.channels().insert(kRgbaNames[c], Imf::Channel(Imf::FLOAT));
            fb.insert(kRgbaNames[c], float_slice(img.rgba.data() + c, 4, img.width));
        }
        if (!img.stderr_rgb.empty()) {
            for (int c = 0; c < 3; ++c) {
                header.channels().insert(kStderrNames[c], Imf::Channel(Imf::FLOAT));
                fb.insert(kStderrNames[c], float_slice(img.stderr_rgb.data() + c, 3, img.width));
            }
        }
        Imf::StdOFStream stream(os, path.c_str());
        Imf::OutputFile file(stream, header);
        file.setFrameBuffer(fb);
        file.writePixels(img.height);
    } catch (const std::exception& e) {
        fail(path, e.what());
    }
    os.close();
    if (!os) fail(path, std::strerror(errno));  // errno of the failed write
}

Image read_exr(const std::string& path) {
    try {
        Imf::InputFile file(path.c_str());
        const Imath::Box2i dw = file.header().dataWindow();
        const int width = dw.max.x - dw.min.x + 1, height = dw.max.y - dw.min.y + 1;
        Image img(width, height);
        const Imf::ChannelList& channels = file.header().channels();
        const bool has_stderr = channels.findChannel(kStderrNames[0]) != nullptr;
        if (has_stderr) img.stderr_rgb.assign(static_cast<size_t>(width) * height * 3, 0.0f);

        // Slices are addressed by absolute data-window coordinates: shift the base pointer.
        const std::ptrdiff_t origin = static_cast<std::ptrdiff_t>(dw.min.y) * width + dw.min.x;
        Imf::FrameBuffer fb;
        for (int c = 0; c < 4; ++c)
            fb.insert(kRgbaNames[c], float_slice(img.rgba.data() - origin * 4 + c, 4, width,
                                                 c == 3 ? 1.0f : 0.0f));
        if (has_stderr)
            for (int c = 0; c < 3; ++c)
                fb.insert(kStderrNames[c],
                          float_slice(img.stderr_rgb.data() - origin * 3 + c, 3, width));
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y, dw.max.y);
        return img;
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        // Not an EXR at all (OpenEXR's text then only repeats the path): name the format.
        const bool exr = path.size() >= 4 && path.compare(path.size() - 4, 4, ".exr") == 0;
        throw Error(exr ? "cannot read image file '" + path + "': " + e.what()
                        : "cannot read '" + path + "' as an OpenEXR image: images are read from the .exr "
                          "that runs write (not the .png)");
    }
}

void write_png(const std::string& path, const Image& img, double exposure) {
    check_image(path, img);
    const size_t pixels = static_cast<size_t>(img.width) * img.height;
    std::vector<std::uint8_t> bytes(pixels * 4);
    for (size_t p = 0; p < pixels; ++p) {
        for (int c = 0; c < 3; ++c) bytes[p * 4 + c] = srgb8(img.rgba[p * 4 + c] * exposure);
        bytes[p * 4 + 3] = 255;  // opaque: the colour already contains the background seen through the volume
    }

    png_image png;
    std::memset(&png, 0, sizeof(png));
    png.version = PNG_IMAGE_VERSION;
    png.width = static_cast<png_uint_32>(img.width);
    png.height = static_cast<png_uint_32>(img.height);
    png.format = PNG_FORMAT_RGBA;  // 8-bit sRGB, straight alpha; libpng adds the sRGB chunk
    const int ok = png_image_write_to_file(&png, path.c_str(), 0, bytes.data(), 0, nullptr);
    if (!ok) {
        const std::string why = png.message;
        png_image_free(&png);
        fail(path, why);
    }
}

}  // namespace nimbus
