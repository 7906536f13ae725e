// Images: OpenEXR round trip bit-exact (with and without the stderr channels, header checked
// with OpenEXR directly), PNG decoded with libpng's low-level reader against the sRGB curve
// evaluated by hand (0 -> 0, 1 -> 255, 0.5 -> 188), exposure, alpha and the sRGB chunk; write
// errors. Not collective: each rank writes its own files.
#include <gtest/gtest.h>
#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <png.h>

#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "io/output/image_io.h"
#include "tests/support/scratch_dir.h"
#include "src/core/error.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

namespace fs = std::filesystem;

std::string rank_file(const test::ScratchDir& dir, const std::string& name) {
    return dir.file("r" + std::to_string(test::world_rank()) + "_" + name);
}

Image awkward_image(int w, int h, bool with_stderr) {
    Image img(w, h);
    const float specials[] = {0.0f, -0.0f, 1.0f, -3.5f, 1e-42f /* denormal */, 3.0e38f,
                              std::numeric_limits<float>::infinity(), 0.1f};
    for (size_t n = 0; n < img.rgba.size(); ++n)
        img.rgba[n] = n % 5 == 0 ? specials[(n / 5) % 8] : static_cast<float>(std::sin(n * 0.37) * 1e3);
    if (with_stderr) {
        img.stderr_rgb.resize(static_cast<size_t>(w) * h * 3);
        for (size_t n = 0; n < img.stderr_rgb.size(); ++n)
            img.stderr_rgb[n] = static_cast<float>(1e-3 * n + 1.0 / 3.0);
    }
    return img;
}

bool bits_equal(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

TEST(Exr, RoundTripIsBitExactWithStderrChannels) {
    test::ScratchDir dir("exr");
    const std::string path = rank_file(dir, "img.exr");
    const Image img = awkward_image(7, 5, true);
    write_exr(path, img);
    EXPECT_FALSE(fs::exists(path + ".tmp"));

    const Image back = read_exr(path);
    EXPECT_EQ(back.width, 7);
    EXPECT_EQ(back.height, 5);
    EXPECT_TRUE(bits_equal(back.rgba, img.rgba));
    EXPECT_TRUE(bits_equal(back.stderr_rgb, img.stderr_rgb));

    Imf::InputFile file(path.c_str());
    EXPECT_EQ(file.header().compression(), Imf::ZIP_COMPRESSION);
    int channels = 0;
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
        EXPECT_EQ(it.channel().type, Imf::FLOAT) << it.name();
        ++channels;
    }
    EXPECT_EQ(channels, 7);
    for (const char* name : {"R", "G", "B", "A", "stderr.R", "stderr.G", "stderr.B"})
        EXPECT_NE(file.header().channels().findChannel(name), nullptr) << name;
}

TEST(Exr, WithoutStderrHasFourChannels) {
    test::ScratchDir dir("exr4");
    const std::string path = rank_file(dir, "img.exr");
    const Image img = awkward_image(3, 4, false);
    write_exr(path, img);
    const Image back = read_exr(path);
    EXPECT_TRUE(bits_equal(back.rgba, img.rgba));
    EXPECT_TRUE(back.stderr_rgb.empty());
    Imf::InputFile file(path.c_str());
    EXPECT_EQ(file.header().channels().findChannel("stderr.R"), nullptr);
}

TEST(Exr, ErrorsNameTheFile) {
    test::ScratchDir dir("exr_err");
    const std::string path = dir.file("missing/img.exr");
    try {
        write_exr(path, awkward_image(2, 2, false));
        ADD_FAILURE() << "no Error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
    EXPECT_THROW(read_exr(dir.file("absent.exr")), Error);
    EXPECT_THROW(write_exr(rank_file(dir, "empty.exr"), Image()), Error);
}

struct DecodedPng {
    bool ok = false;
    bool srgb_chunk = false;
    int bit_depth = 0, color_type = 0;
    png_uint_32 width = 0, height = 0;
    std::vector<unsigned char> rgba;
};

// libpng's low-level reader; only trivially destructible locals live in the setjmp frame.
void decode_png(const char* path, DecodedPng* out) {
    std::FILE* fp = std::fopen(path, "rb");
    if (fp == nullptr) return;
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    png_infop info = png_create_info_struct(png);
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_read_struct(&png, &info, nullptr);
        std::fclose(fp);
        return;
    }
    png_init_io(png, fp);
    png_read_png(png, info, PNG_TRANSFORM_IDENTITY, nullptr);
    out->width = png_get_image_width(png, info);
    out->height = png_get_image_height(png, info);
    out->bit_depth = png_get_bit_depth(png, info);
    out->color_type = png_get_color_type(png, info);
    out->srgb_chunk = png_get_valid(png, info, PNG_INFO_sRGB) != 0;
    const size_t row_bytes = png_get_rowbytes(png, info);
    out->rgba.resize(row_bytes * out->height);
    png_bytepp rows = png_get_rows(png, info);
    for (png_uint_32 y = 0; y < out->height; ++y)
        std::memcpy(out->rgba.data() + y * row_bytes, rows[y], row_bytes);
    out->ok = true;
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(fp);
}

TEST(Png, SignatureSrgbChunkAndKnownValues) {
    test::ScratchDir dir("png");
    const std::string path = rank_file(dir, "preview.png");
    // One row: linear value -> expected 8-bit sRGB code, worked out from IEC 61966-2-1:
    //   0.5:    1.055 * 0.5^(1/2.4) - 0.055 = 0.73536 -> 187.5 -> 188
    //   0.002:  12.92 * 0.002 = 0.02584 -> 6.59 -> 7        (linear segment)
    //   0.2:    1.055 * 0.2^(1/2.4) - 0.055 = 0.48453 -> 123.56 -> 124
    struct Case { float v; int code; };
    const Case cases[] = {{0.0f, 0}, {1.0f, 255}, {0.5f, 188}, {0.002f, 7},
                          {0.2f, 124}, {4.0f, 255}, {-1.0f, 0}};
    const int w = static_cast<int>(std::size(cases));
    Image img(w, 2);
    for (int x = 0; x < w; ++x) {
        float* p = img.pixel(x, 0);
        p[0] = p[1] = p[2] = cases[x].v;
        p[3] = 1.0f;
        float* q = img.pixel(x, 1);  // second row: distinct channels and alpha
        q[0] = 1.0f;
        q[1] = 0.0f;
        q[2] = 0.5f;
        q[3] = x == 0 ? 0.5f : (x == 1 ? 0.0f : 2.0f);
    }
    write_png(path, img, 1.0);
    EXPECT_FALSE(fs::exists(path + ".tmp"));

    unsigned char sig[8] = {0};
    std::FILE* f = std::fopen(path.c_str(), "rb");
    ASSERT_NE(f, nullptr);
    ASSERT_EQ(std::fread(sig, 1, 8, f), 8u);
    std::fclose(f);
    const unsigned char expected_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    EXPECT_EQ(std::memcmp(sig, expected_sig, 8), 0);

    DecodedPng png;
    decode_png(path.c_str(), &png);
    ASSERT_TRUE(png.ok);
    EXPECT_TRUE(png.srgb_chunk);
    EXPECT_EQ(png.bit_depth, 8);
    EXPECT_EQ(png.color_type, PNG_COLOR_TYPE_RGB_ALPHA);
    ASSERT_EQ(png.width, static_cast<png_uint_32>(w));
    ASSERT_EQ(png.height, 2u);
    for (int x = 0; x < w; ++x) {
        const unsigned char* p = &png.rgba[static_cast<size_t>(x) * 4];
        for (int c = 0; c < 3; ++c) EXPECT_EQ(p[c], cases[x].code) << "v = " << cases[x].v;
        EXPECT_EQ(p[3], 255);
        const unsigned char* q = &png.rgba[(static_cast<size_t>(w) + x) * 4];
        EXPECT_EQ(q[0], 255);
        EXPECT_EQ(q[1], 0);
        EXPECT_EQ(q[2], 188);
        EXPECT_EQ(q[3], 255);  // the preview is opaque: colour already holds the background
    }
}

TEST(Png, ExposureScalesBeforeTheCurve) {
    test::ScratchDir dir("png_exp");
    const std::string path = rank_file(dir, "exposed.png");
    Image img(3, 1);
    const float v[3] = {0.25f, 0.001f, 0.6f};
    for (int x = 0; x < 3; ++x) {
        float* p = img.pixel(x, 0);
        p[0] = p[1] = p[2] = v[x];
        p[3] = 0.25f;  // alpha is an opacity: exposure must not touch it
    }
    write_png(path, img, 2.0);
    DecodedPng png;
    decode_png(path.c_str(), &png);
    ASSERT_TRUE(png.ok);
    // 2 * 0.25 = 0.5 -> 188; 2 * 0.001 = 0.002 -> 7; 2 * 0.6 = 1.2 -> clamped -> 255.
    const int codes[3] = {188, 7, 255};
    for (int x = 0; x < 3; ++x) {
        EXPECT_EQ(png.rgba[x * 4 + 0], codes[x]);
        EXPECT_EQ(png.rgba[x * 4 + 3], 255);  // opaque preview
    }
}

TEST(Png, UnwritableFolderThrowsAndLeavesNoTemporary) {
    test::ScratchDir dir("png_err");
    const std::string path = dir.file("missing/preview.png");
    Image img(2, 2);
    EXPECT_THROW(write_png(path, img, 1.0), Error);
    EXPECT_FALSE(fs::exists(path + ".tmp"));
    EXPECT_FALSE(fs::exists(path));
}

}  // namespace
}  // namespace nimbus
