#include "core/image_io.h"

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/error.h"
#include "core/texture.h"

namespace obscura {
namespace fs = std::filesystem;
namespace {

// Temporary sibling of `path` (same directory, so rename is atomic).
std::string temporaryPath(const std::string& path) {
  const fs::path p(path);
  const std::string name = "." + p.filename().string() + ".tmp" + std::to_string(getpid());
  return (p.parent_path() / name).string();
}

// Writes `pixels` (interleaved, of type `bufferType`) in the file format
// `format`; OIIO converts to spec.format on the way.
void writeAtomically(const std::string& path, const char* format, const OIIO::ImageSpec& spec,
                     OIIO::TypeDesc bufferType, const void* pixels) {
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty() && !fs::is_directory(parent))
    throw Error(path + ": cannot write: directory '" + parent.string() + "' does not exist");
  const std::string tmp = temporaryPath(path);
  auto out = OIIO::ImageOutput::create(format);
  if (!out) throw Error(path + ": OpenImageIO has no '" + format + "' writer: " + OIIO::geterror());
  if (!out->open(tmp, spec)) {
    const std::string e = out->geterror();
    std::remove(tmp.c_str());
    throw Error(path + ": cannot open for writing: " + e);
  }
  const bool ok = out->write_image(bufferType, pixels);
  std::string e = ok ? "" : out->geterror();
  const bool closed = out->close();
  if (ok && !closed) e = out->geterror();
  if (!ok || !closed) {
    std::remove(tmp.c_str());
    throw Error(path + ": write failed: " + e);
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw Error(path + ": cannot rename the temporary file into place: " + ec.message());
  }
}

}  // namespace

void writeExr(const std::string& path, const Film& film, const ExrOptions& options) {
  const std::vector<int>& chans = film.channels();
  const int nc = int(chans.size());
  OIIO::ImageSpec spec(film.width(), film.height(), nc, options.half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
  spec.channelnames.clear();
  for (int c : chans) spec.channelnames.emplace_back(channelName(c));
  spec.alpha_channel = 3;
  spec.z_channel = -1;
  for (int i = 0; i < nc; ++i)
    if (chans[size_t(i)] == kZ) spec.z_channel = i;
  spec.attribute("compression", "zip");
  spec.attribute("oiio:ColorSpace", "Linear");
  for (const HeaderAttribute& a : options.attributes) {
    if (auto* s = std::get_if<std::string>(&a.value)) spec.attribute(a.name, *s);
    else if (auto* i = std::get_if<int>(&a.value)) spec.attribute(a.name, *i);
    else if (auto* f = std::get_if<float>(&a.value)) spec.attribute(a.name, *f);
    else {
      const auto& m = std::get<std::vector<float>>(a.value);
      if (m.size() == 16) spec.attribute(a.name, OIIO::TypeMatrix44, m.data());
    }
  }
  // Interleave the planes (OIIO's native layout); float, converted on write.
  std::vector<float> pixels(size_t(film.width()) * film.height() * nc);
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x)
      for (int i = 0; i < nc; ++i)
        pixels[(size_t(y) * film.width() + x) * nc + i] = film.at(chans[size_t(i)], x, y);
  writeAtomically(path, "openexr", spec, OIIO::TypeDesc::FLOAT, pixels.data());
}

unsigned char linearToSrgb8(float v) {
  const float c = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
  return (unsigned char)std::lround(255.0f * linearToSrgb(c));
}

void writePreviewPng(const std::string& path, const Film& film) {
  const int w = film.width(), h = film.height();
  std::vector<unsigned char> px(size_t(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const float v = film.at(kR + c, x, y);
        px[(size_t(y) * w + x) * 3 + c] = linearToSrgb8(v);
      }
  writePngRgb8(path, w, h, px.data());
}

void writePngRgb8(const std::string& path, int width, int height, const unsigned char* rgb) {
  OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  writeAtomically(path, "png", spec, OIIO::TypeDesc::UINT8, rgb);
}

std::string readExrAttribute(const std::string& path, const std::string& name) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw Error(path + ": cannot open: " + OIIO::geterror());
  const std::string v = in->spec().get_string_attribute(name);
  in->close();
  return v;
}

}  // namespace obscura
