// Images: OpenEXR (linear float RGBA, the data) and PNG (an sRGB preview). Not collective.
// The writers write path itself and remove it if they fail; a run passes the temporary name
// from its OutputFiles (io/output/output_files.h), which makes all its outputs final together.
#pragma once

#include <string>

#include "src/render/image.h"

namespace nimbus {

// Linear float32 RGBA; if img.stderr_rgb is set, also channels stderr.R/G/B.
void write_exr(const std::string& path, const Image& img);
Image read_exr(const std::string& path);
// 8-bit sRGB preview, opaque: each colour value v becomes srgb(clamp(v * exposure, 0, 1)).
void write_png(const std::string& path, const Image& img, double exposure);

}  // namespace nimbus
