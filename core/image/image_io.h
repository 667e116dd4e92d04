// Image output: the film as a multi-channel EXR (OpenEXR, straight from the
// film's planes), and an sRGB PNG preview (stb_image_write). Neither loads
// OpenImageIO, which costs ~0.4 s of start-up (core/image/oiio_module.h). Both are written atomically: to a temporary file in the
// destination's directory, then renamed over the destination, so a failed or
// interrupted write never leaves a truncated file where a good one was.
// Several files that belong together (a pass and its preview) go through one
// OutputSet: all are written first, then all are moved into place, so either
// every destination is new or none changed.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <variant>
#include <vector>

#include "core/image/film.h"

namespace obscura {

struct HeaderAttribute {
  std::string name;
  std::variant<std::string, int, float, std::vector<float>> value;  // vector: 16 floats = 4x4 matrix
};

// EXR compressions offered (all lossless). Sizes and write times at 1080p
// are in docs/performance.md "Start-up and file speed" (bench/bench_exr_write.cpp).
enum class ExrCompression { None, Rle, Zips, Zip, Piz };
// "none", "rle", "zips", "zip", "piz": the names of the EXR `compression`
// attribute as OpenImageIO and Nuke show them.
const char* exrCompressionName(ExrCompression c);
// Throws obscura::Error "`what`: unknown compression 'x' (one of ...)".
ExrCompression exrCompressionFromName(const std::string& name, const std::string& what);

struct ExrOptions {
  // 16-bit half floats instead of 32-bit floats for the pass, alpha, albedo,
  // shaded and the extra planes; N.X/Y/Z and Z stay 32-bit (exrKeepsFloat).
  bool half = false;
  // Extra planes whose name starts with one of these stay 32-bit floats with
  // `half` (Cryptomatte ids are float bit patterns: docs/exr.md "Cryptomatte").
  std::vector<std::string> floatChannelPrefixes;
  std::vector<HeaderAttribute> attributes;
  // Recorded in the file's standard `compression` attribute.
  ExrCompression compression = ExrCompression::Zip;
  // zlib level for zip/zips, 1-9; 0 = OpenEXR's default.
  int zipLevel = 0;
  // OpenEXR's compression threads; 0 = TBB's current limit (--threads).
  int threads = 0;
};

// True for the fixed channels written 32-bit float even under --half: the
// normal (half's 11-bit significand leaves ~5e-4 of a unit vector) and the
// depth (half overflows at 65504 and quantizes depths of a few hundred
// units to a fraction of a unit).
bool exrKeepsFloat(int channel);

// Throws obscura::Error naming the path on failure (nothing is left behind).
// Header: the channels (OpenEXR sorts them by name), the data window (the
// film's window) and display window (the frame), `compression`,
// `chromaticities`, `capDate` (the local time, "YYYY:MM:DD HH:MM:SS", which
// OpenImageIO shows as DateTime) and `options.attributes` (string, int,
// float, m44f).
// The EXR is written in bands of scanlines straight from the film's planes,
// so writing needs no second copy of the film. Its channels may mix half
// and float (OpenEXR stores a pixel type per channel). The header also
// carries the standard `chromaticities` (Rec.709 primaries, D65 white: the
// film is linear Rec.709).
void writeExr(const std::string& path, const Film& film, const ExrOptions& options);

// A float32 RGB EXR of width x height texels from interleaved RGB floats,
// top row first (an environment map: `obscura sky`), zip-compressed, with
// the header of writeExr (chromaticities, capDate, `attributes`). Written
// atomically like writeExr; throws obscura::Error naming the path.
void writeRgbExr(const std::string& path, int width, int height, const std::vector<float>& rgb,
                 const std::vector<HeaderAttribute>& attributes);

// Files written together: each add*() writes a temporary sibling of its
// destination (throwing obscura::Error naming the destination on failure);
// commit() moves them all into place. If a move fails, the destinations
// already replaced get their previous contents back (kept as hard-linked
// backups until the end), so a failure leaves every destination as it was.
// Without commit(), the destructor removes the temporaries.
class OutputSet {
 public:
  OutputSet() = default;
  OutputSet(const OutputSet&) = delete;
  OutputSet& operator=(const OutputSet&) = delete;
  ~OutputSet();
  void addExr(const std::string& path, const Film& film, const ExrOptions& options);
  void addPreviewPng(const std::string& path, const Film& film);
  // An 8-bit sRGB PNG from interleaved RGB bytes, row-major, top row first.
  void addPngRgb8(const std::string& path, int width, int height, const unsigned char* rgb);
  // A file of these bytes (text: JSON, CSV, SVG), every write checked.
  void addText(const std::string& path, const std::string& bytes);
  // A file written by `write`, which writes the temporary path it is given
  // or throws (the temporary is then removed): for writers of their own,
  // such as `obscura merge`.
  void addFile(const std::string& path, const std::function<void(const std::string& tmp)>& write);
  void commit();

 private:
  struct Staged {
    std::string dest, tmp;
  };
  std::vector<Staged> staged_;
};

// Refuses, before any work, an output that cannot be written: its directory
// is missing or not writable, or the path is a directory (the message names
// the path).
// and a file name too long for its temporary (checkOutputName).
void checkWritable(const std::string& path);
// Bytes the temporaries add to an output's file name: ".NAME.tmpPID" (and
// ".bak"): a dot, four bytes and a process id of at most 7 digits.
constexpr size_t kTemporaryNameExtra = 1 + 4 + 7;
// Refuses an output whose file name plus `extra` bytes passes the file
// system's NAME_MAX (pathconf of its directory, else 255): the temporary
// written beside it could not be created, and the render would be lost at
// 100 %. The message starts with `what` (e.g. "-o ") and gives the limit.
void checkOutputName(const std::string& path, const std::string& what, size_t extra = kTemporaryNameExtra);
// Bytes a film of w x h pixels takes (with or without AOVs, with or without
// the albedo AOV).
uint64_t filmBytes(int width, int height, bool aovs, bool albedo = true);
// Physical memory the system reports as available (MemAvailable), plus
// the whole-image blocks this process keeps for reuse (core/util/large_vector.h);
// 0 if unknown.
uint64_t availableMemoryBytes();
// True if the file starts with OpenEXR's magic number; throws
// obscura::Error naming the path if it cannot be read.
bool isExrFile(const std::string& path);
// A string attribute of an image file's header ("" if absent or not a
// string); throws obscura::Error naming the path if the file cannot be
// opened. EXR through OpenEXR, other formats through OpenImageIO's module.
std::string readExrAttribute(const std::string& path, const std::string& name);
// Every channel of an EXR, as 32-bit floats (half channels converted
// exactly), over its data window, in the file's channel order (sorted by
// name), with the header's string, int, float and 4x4 matrix attributes
// (other types are skipped). For reading passes back (the Python module's
// read_exr); throws obscura::Error naming the path.
struct ExrImage {
  int width = 0, height = 0;   // the data window
  int originX = 0, originY = 0;  // its origin in the display window
  std::vector<std::string> names;
  std::vector<std::vector<float>> planes;  // row-major, one per name
  std::vector<HeaderAttribute> attributes;
};
ExrImage readExrImage(const std::string& path);
// sRGB preview of the pass (R,G,B over black); 8-bit PNG.
void writePreviewPng(const std::string& path, const Film& film);
// An 8-bit sRGB PNG from interleaved RGB bytes, row-major, top row first.
void writePngRgb8(const std::string& path, int width, int height, const unsigned char* rgb);
// A file of these bytes, written atomically like writeExr (OutputSet::addText).
void writeTextFile(const std::string& path, const std::string& bytes);
// sRGB encoding of a linear value in [0, 1] (clamped), as a byte.
unsigned char linearToSrgb8(float v);

}  // namespace obscura
