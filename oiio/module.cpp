// libobscura_oiio.so: what Obscura reads and writes through OpenImageIO,
// loaded on first need (core/image/oiio_module.h). Linking OpenImageIO into the
// program would load its ~250 libraries at every start.
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>

#include <obscura/error.h>
#include "core/image/oiio_module.h"
#include "core/image/texture.h"
#include "core/util/memory_budget.h"

namespace obscura {

void mergeRegionsOiio(const std::string& output, const std::vector<std::string>& paths);  // oiio/merge.cpp

namespace {

// libpng reports a damaged file through its default handler too, which
// prints "libpng error: ..." straight to stderr (OpenImageIO installs its own
// handler only on some of its read structs), beside the error OpenImageIO
// returns. While a map is read (at load time, on the loading thread) fd 2
// goes to a temporary file; afterwards libpng's lines are dropped - the
// error OpenImageIO returns says the same - and anything else is passed on.
class QuietLibpng {
 public:
  QuietLibpng() {
    std::fflush(stderr);
    tmp_ = std::tmpfile();
    saved_ = tmp_ ? ::dup(2) : -1;
    if (saved_ >= 0 && ::dup2(::fileno(tmp_), 2) < 0) ::close(saved_), saved_ = -1;
  }
  ~QuietLibpng() {
    if (saved_ < 0) {
      if (tmp_) std::fclose(tmp_);
      return;
    }
    std::fflush(stderr);
    ::dup2(saved_, 2);
    ::close(saved_);
    std::rewind(tmp_);
    char line[4096];
    while (std::fgets(line, sizeof line, tmp_))
      if (std::strncmp(line, "libpng ", 7) != 0) std::fputs(line, stderr);
    std::fclose(tmp_);
  }
  QuietLibpng(const QuietLibpng&) = delete;
  QuietLibpng& operator=(const QuietLibpng&) = delete;

 private:
  std::FILE* tmp_ = nullptr;
  int saved_ = -1;
};

// OpenImageIO's error text, which may span lines, as one clause.
std::string oneLine(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ';';
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == ';' && (out.empty() || out.back() == ';' || i + 1 == s.size())) continue;
    out += s[i];
    if (s[i] == ';') out += ' ';
  }
  while (!out.empty() && (out.back() == ' ' || out.back() == ';')) out.pop_back();
  return out;
}

void readFirstChannel(const std::string& path, int& w, int& h, std::vector<float>& texels) {
  QuietLibpng quiet;  // around opening and reading: both may meet the damage
  // ImageInput rather than ImageBuf: ImageBuf leaks the error text of a
  // file that fails to read (OpenImageIO 2.4, seen by LeakSanitizer).
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw Error(path + ": cannot read the height map: " + oneLine(OIIO::geterror()));
  const OIIO::ImageSpec& spec = in->spec();
  w = spec.width, h = spec.height;
  if (w < 1 || h < 1 || spec.nchannels < 1) throw Error(path + ": the height map is empty");
  // The header's size, before any texel is decoded (a 65-byte PNG may claim 30000 x 30000).
  requireMemory(uint64_t(w) * uint64_t(h) * sizeof(float), path + ": the height map's " + std::to_string(w) + "x" + std::to_string(h) + " texels");
  texels.resize(size_t(w) * size_t(h));
  // The first channel of the first subimage, rows top first.
  if (!in->read_image(0, 0, 0, 1, OIIO::TypeDesc::FLOAT, texels.data()))
    throw Error(path + ": cannot read the height map: " + oneLine(in->geterror()));
}

// An environment map as linear RGB, rows top first: grey images replicate
// their channel; integer formats (8- and 16-bit PNG, JPEG, TIFF) are
// decoded from sRGB unless the file says it is linear, as Blender's image
// loader treats them by default.
void readRgb(const std::string& path, int& w, int& h, std::vector<float>& rgb) {
  QuietLibpng quiet;
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw Error(path + ": cannot read the environment map: " + oneLine(OIIO::geterror()));
  const OIIO::ImageSpec& spec = in->spec();
  w = spec.width, h = spec.height;
  if (w < 1 || h < 1 || spec.nchannels < 1) throw Error(path + ": the environment map is empty");
  const int channels = std::min(spec.nchannels, 3);
  // The raw channels and the RGB made of them (then the map's tables: core/scene/environment.cpp).
  requireMemory(uint64_t(w) * uint64_t(h) * uint64_t(channels + 3) * sizeof(float),
                path + ": the environment map's " + std::to_string(w) + "x" + std::to_string(h) + " texels");
  std::vector<float> raw(size_t(w) * size_t(h) * size_t(channels));
  if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, raw.data()))
    throw Error(path + ": cannot read the environment map: " + oneLine(in->geterror()));
  const std::string space = spec.get_string_attribute("oiio:ColorSpace");
  const bool srgb = !spec.format.is_floating_point() && space != "Linear" && space != "linear";
  rgb.resize(size_t(w) * size_t(h) * 3);
  for (size_t i = 0; i < size_t(w) * size_t(h); ++i)
    for (int c = 0; c < 3; ++c) {
      const float v = raw[i * size_t(channels) + size_t(channels == 3 ? c : 0)];
      rgb[3 * i + size_t(c)] = srgb ? srgbToLinear(v) : v;
    }
}

PassImage readPass(const std::string& path) {
  OIIO::ImageBuf buf(path);
  {
    // The header's size first: read() decodes every channel as float.
    QuietLibpng quiet;
    auto in = OIIO::ImageInput::open(path);
    if (!in) throw Error(path + ": cannot read: " + oneLine(OIIO::geterror()));
    const OIIO::ImageSpec& h = in->spec();
    requireMemory(uint64_t(std::max(h.width, 0)) * uint64_t(std::max(h.height, 0)) * uint64_t(std::max(h.nchannels, 0) + 4) * sizeof(float),
                  path + ": " + std::to_string(h.width) + "x" + std::to_string(h.height) + " pixels");
  }
  if (!buf.read(0, 0, true, OIIO::TypeDesc::FLOAT)) throw Error(path + ": cannot read: " + buf.geterror());
  const OIIO::ImageSpec& spec = buf.spec();
  PassImage p;
  p.width = spec.width;
  p.height = spec.height;
  std::vector<float>* planes[4] = {&p.r, &p.g, &p.b, &p.a};
  const char* names[4] = {"R", "G", "B", "A"};
  for (int c = 0; c < 4; ++c) {
    const int index = spec.channelindex(names[c]);
    if (index < 0) throw Error(path + ": channel " + names[c] + " is missing (not an obscura pass?)");
    planes[c]->resize(p.pixels());
    // The data window, wherever it starts.
    if (!buf.get_pixels(OIIO::ROI(spec.x, spec.x + p.width, spec.y, spec.y + p.height, 0, 1, index, index + 1),
                        OIIO::TypeDesc::FLOAT, planes[c]->data()))
      throw Error(path + ": cannot read channel " + names[c] + ": " + buf.geterror());
  }
  return p;
}

std::string readStringAttribute(const std::string& path, const std::string& name) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw Error(path + ": cannot open: " + oneLine(OIIO::geterror()));
  const std::string v = in->spec().get_string_attribute(name);
  in->close();
  return v;
}

const OiioModule kModule{kOiioModuleAbi, readFirstChannel, readRgb, readPass, readStringAttribute, mergeRegionsOiio};

}  // namespace
}  // namespace obscura

extern "C" __attribute__((visibility("default"))) const obscura::OiioModule* obscura_oiio_module() {
  return &obscura::kModule;
}
