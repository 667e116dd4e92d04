#include "core/image_io.h"

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/error.h"
#include "core/texture.h"

namespace obscura {
namespace fs = std::filesystem;
namespace {

// Temporary sibling of `path` (same directory, so rename is atomic); `tag`
// tells a backup from a new file.
std::string siblingPath(const std::string& path, const char* tag) {
  const fs::path p(path);
  const std::string name = "." + p.filename().string() + tag + std::to_string(getpid());
  return (p.parent_path() / name).string();
}

// Opens `tmp` for `format` or throws naming `path` (the destination).
std::unique_ptr<OIIO::ImageOutput> openOutput(const std::string& path, const std::string& tmp, const char* format,
                                              const OIIO::ImageSpec& spec) {
  checkWritable(path);
  auto out = OIIO::ImageOutput::create(format);
  if (!out) throw Error(path + ": OpenImageIO has no '" + format + "' writer: " + OIIO::geterror());
  if (!out->open(tmp, spec)) {
    const std::string e = out->geterror();
    std::remove(tmp.c_str());
    throw Error(path + ": cannot open for writing: " + e);
  }
  return out;
}

// Closes `out`, or removes `tmp` and throws naming `path`.
void closeOutput(OIIO::ImageOutput& out, bool ok, const std::string& path, const std::string& tmp) {
  std::string e = ok ? "" : out.geterror();
  const bool closed = out.close();
  if (ok && !closed) e = out.geterror();
  if (!ok || !closed) {
    std::remove(tmp.c_str());
    throw Error(path + ": write failed: " + e);
  }
}

// Writes the film's channels to `tmp` as an EXR, a band of scanlines at a
// time (interleaved, OIIO's native layout).
void writeExrFile(const std::string& path, const std::string& tmp, const Film& film, const ExrOptions& options) {
  const std::vector<int>& chans = film.channels();
  const int nc = int(chans.size());
  OIIO::ImageSpec spec(film.width(), film.height(), nc, options.half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
  // The data window is the film's window, the display window the frame
  // (equal but for a --region render; README "Regions and merging").
  spec.x = film.originX(), spec.y = film.originY();
  spec.full_x = 0, spec.full_y = 0, spec.full_width = film.fullWidth(), spec.full_height = film.fullHeight();
  spec.channelnames.clear();
  for (int c : chans) spec.channelnames.emplace_back(film.name(c));
  if (options.half) {
    // Per-channel pixel types: OIIO converts the float bands below to each.
    bool mixed = false;
    for (int c : chans) {
      const std::string& n = film.name(c);
      const bool keep = c < kChannelCount ? exrKeepsFloat(c)
                                          : std::any_of(options.floatChannelPrefixes.begin(), options.floatChannelPrefixes.end(),
                                                        [&](const std::string& p) { return n.compare(0, p.size(), p) == 0; });
      spec.channelformats.push_back(keep ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::HALF);
      mixed |= keep;
    }
    if (!mixed) spec.channelformats.clear();
  }
  spec.alpha_channel = 3;
  spec.z_channel = -1;
  for (int i = 0; i < nc; ++i)
    if (chans[size_t(i)] == kZ) spec.z_channel = i;
  spec.attribute("compression", "zip");
  spec.attribute("oiio:ColorSpace", "Linear");
  // CIE xy of the Rec.709 / sRGB primaries R, G, B and of the D65 white
  // (ITU-R BT.709): what linear sRGB textures and a grey sky make.
  static const float rec709[8] = {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f};
  spec.attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8), rec709);
  for (const HeaderAttribute& a : options.attributes) {
    if (auto* s = std::get_if<std::string>(&a.value)) spec.attribute(a.name, *s);
    else if (auto* i = std::get_if<int>(&a.value)) spec.attribute(a.name, *i);
    else if (auto* f = std::get_if<float>(&a.value)) spec.attribute(a.name, *f);
    else {
      const auto& m = std::get<std::vector<float>>(a.value);
      if (m.size() == 16) spec.attribute(a.name, OIIO::TypeMatrix44, m.data());
    }
  }
  auto out = openOutput(path, tmp, "openexr", spec);
  // 64 rows: a multiple of ZIP's 16-line blocks, and a few MiB at most.
  const int band = 64;
  const size_t w = size_t(film.width());
  std::vector<float> rows(w * size_t(std::min(band, film.height())) * size_t(nc));
  bool ok = true;
  for (int y0 = 0; ok && y0 < film.height(); y0 += band) {
    const int y1 = std::min(film.height(), y0 + band);
    for (int y = y0; y < y1; ++y)
      for (int i = 0; i < nc; ++i) {
        const float* src = film.plane(chans[size_t(i)]) + size_t(y) * w;
        float* dst = rows.data() + size_t(y - y0) * w * size_t(nc) + size_t(i);
        for (size_t x = 0; x < w; ++x) dst[x * size_t(nc)] = src[x];
      }
    // Scanlines are numbered in the frame: the data window starts at spec.y.
    ok = out->write_scanlines(spec.y + y0, spec.y + y1, 0, OIIO::TypeDesc::FLOAT, rows.data());
  }
  closeOutput(*out, ok, path, tmp);
}

void writePngFile(const std::string& path, const std::string& tmp, int width, int height, const unsigned char* rgb) {
  OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  auto out = openOutput(path, tmp, "png", spec);
  const bool ok = out->write_image(OIIO::TypeDesc::UINT8, rgb);
  closeOutput(*out, ok, path, tmp);
}

std::vector<unsigned char> previewPixels(const Film& film) {
  const int w = film.width(), h = film.height();
  std::vector<unsigned char> px(size_t(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) px[(size_t(y) * w + x) * 3 + c] = linearToSrgb8(film.plane(kR + c)[size_t(y) * w + x]);
  return px;
}

}  // namespace

bool exrKeepsFloat(int channel) { return channel == kNX || channel == kNY || channel == kNZ || channel == kZ; }

void checkWritable(const std::string& path) {
  const fs::path p(path);
  const fs::path parent = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  std::error_code ec;
  if (!fs::is_directory(parent, ec))
    throw Error(path + ": cannot write: directory '" + parent.string() + "' does not exist");
  if (fs::is_directory(p, ec)) throw Error(path + ": cannot write: it is a directory");
  if (::access(parent.c_str(), W_OK | X_OK) != 0)
    throw Error(path + ": cannot write: directory '" + parent.string() + "' is not writable");
}

uint64_t filmBytes(int width, int height, bool aovs) {
  return uint64_t(std::max(width, 0)) * uint64_t(std::max(height, 0)) * uint64_t(aovs ? kChannelCount : 4) *
         sizeof(float);
}

uint64_t availableMemoryBytes() {
  std::FILE* f = std::fopen("/proc/meminfo", "r");
  if (!f) return 0;
  char line[256];
  uint64_t kib = 0;
  while (std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "MemAvailable: %" SCNu64 " kB", &kib) == 1) break;
  std::fclose(f);
  return kib * 1024;
}

OutputSet::~OutputSet() {
  for (const Staged& s : staged_) std::remove(s.tmp.c_str());
}

void OutputSet::addExr(const std::string& path, const Film& film, const ExrOptions& options) {
  Staged s{path, siblingPath(path, ".tmp")};
  writeExrFile(path, s.tmp, film, options);
  staged_.push_back(std::move(s));
}

void OutputSet::addPngRgb8(const std::string& path, int width, int height, const unsigned char* rgb) {
  Staged s{path, siblingPath(path, ".tmp")};
  writePngFile(path, s.tmp, width, height, rgb);
  staged_.push_back(std::move(s));
}

void OutputSet::addFile(const std::string& path, const std::function<void(const std::string& tmp)>& write) {
  checkWritable(path);
  Staged s{path, siblingPath(path, ".tmp")};
  try {
    write(s.tmp);
  } catch (...) {
    std::remove(s.tmp.c_str());
    throw;
  }
  staged_.push_back(std::move(s));
}

void OutputSet::addPreviewPng(const std::string& path, const Film& film) {
  const std::vector<unsigned char> px = previewPixels(film);
  addPngRgb8(path, film.width(), film.height(), px.data());
}

void OutputSet::commit() {
  // Keep each destination's current file under a second name (a hard link:
  // no copy) so a later failed move can put it back.
  std::vector<std::string> backups(staged_.size());
  for (size_t i = 0; i < staged_.size(); ++i) {
    std::error_code ec;
    if (!fs::exists(staged_[i].dest, ec)) continue;
    backups[i] = siblingPath(staged_[i].dest, ".bak");
    fs::remove(backups[i], ec);
    fs::create_hard_link(staged_[i].dest, backups[i], ec);
    if (ec) backups[i].clear();  // no hard links here: the move itself is still atomic per file
  }
  auto dropBackups = [&] {
    for (const std::string& b : backups)
      if (!b.empty()) std::remove(b.c_str());
  };
  for (size_t i = 0; i < staged_.size(); ++i) {
    std::error_code ec;
    fs::rename(staged_[i].tmp, staged_[i].dest, ec);
    if (!ec) continue;
    // Undo the moves already made: restore the old file or remove the new one.
    for (size_t j = 0; j < i; ++j) {
      std::error_code ignored;
      if (!backups[j].empty())
        fs::rename(backups[j], staged_[j].dest, ignored);
      else
        fs::remove(staged_[j].dest, ignored);
    }
    dropBackups();
    throw Error(staged_[i].dest + ": cannot rename the temporary file into place: " + ec.message());
  }
  dropBackups();
  staged_.clear();
}

void writeExr(const std::string& path, const Film& film, const ExrOptions& options) {
  OutputSet out;
  out.addExr(path, film, options);
  out.commit();
}

unsigned char linearToSrgb8(float v) {
  const float c = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
  return (unsigned char)std::lround(255.0f * linearToSrgb(c));
}

void writePreviewPng(const std::string& path, const Film& film) {
  OutputSet out;
  out.addPreviewPng(path, film);
  out.commit();
}

void writePngRgb8(const std::string& path, int width, int height, const unsigned char* rgb) {
  OutputSet out;
  out.addPngRgb8(path, width, height, rgb);
  out.commit();
}

std::string readExrAttribute(const std::string& path, const std::string& name) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw Error(path + ": cannot open: " + OIIO::geterror());
  const std::string v = in->spec().get_string_attribute(name);
  in->close();
  return v;
}

}  // namespace obscura
