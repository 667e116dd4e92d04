// Cryptomatte ID mattes (docs/exr.md "Cryptomatte"): object and material layers
// after the public Cryptomatte specification (Psyop, v1.2).
//
// - A name is hashed with MurmurHash3_x86_32 (seed 0) over its UTF-8 bytes;
//   the 32 bits are stored as a float32 id, except that a hash whose
//   exponent bits are all 0 (zero/denormal) or all 1 (inf/NaN) gets the
//   lowest exponent bit flipped, so every id is a finite normal float.
// - Per pixel, every camera sample weighs 1/spp (the pixel filter is
//   importance-sampled: core/render/gbuffer.h cameraSampleFilm); an id's coverage
//   is (samples that saw it) / spp, so a pixel's coverages sum to its alpha.
//   Matte objects are holdouts (no id), camera-invisible objects are never
//   seen. Ids are ranked by coverage, largest first; equal coverages by the
//   id's 32 bits ascending (a tie-break that depends on nothing but the
//   names).
// - Layer `<Type>NN` (NN = 00, 01, ...) holds ranks 2NN and 2NN+1 as
//   R = id, G = coverage, B = id, A = coverage; an absent rank is 0, 0.
// - The header carries cryptomatte/<key>/name, hash, conversion and the
//   manifest (JSON {name: "8 hex digits of the id's bits"}), key = the
//   first 7 hex digits of the id of the layer's name.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/image/film.h"
#include "core/image/image_io.h"

namespace obscura {

class Scene;
struct SurfaceHit;

// MurmurHash3_x86_32 of `data` (Austin Appleby's public-domain algorithm).
uint32_t murmurHash3_x86_32(std::string_view data, uint32_t seed = 0);
// The spec's uint32_to_float32 conversion, as bits: the hash with its
// lowest exponent bit flipped when the exponent is 0 or 255.
uint32_t cryptomatteIdBits(uint32_t hash);
float bitsToFloat(uint32_t bits);
uint32_t floatToBits(float f);
// The id of a name (bits), and its manifest text ("%08x" of the bits).
inline uint32_t cryptomatteNameId(std::string_view name) { return cryptomatteIdBits(murmurHash3_x86_32(name)); }
std::string cryptomatteHex(uint32_t bits);
// The metadata key of a layer: the first 7 hex digits of its name's id.
std::string cryptomatteKey(std::string_view layerName);

enum class CryptomatteType : uint8_t { Object, Material };
inline constexpr const char* kCryptoObject = "CryptoObject";
inline constexpr const char* kCryptoMaterial = "CryptoMaterial";
inline const char* cryptomatteLayerName(CryptomatteType t) {
  return t == CryptomatteType::Object ? kCryptoObject : kCryptoMaterial;
}

inline constexpr int kDefaultCryptomatteRanks = 6;  // the spec's suggested default
inline constexpr int kMaxCryptomatteRanks = 32;     // 16 RGBA layers per type

// What `--cryptomatte` / `--cryptomatte-ranks` ask for (off by default).
struct CryptomatteSettings {
  bool object = false, material = false;
  int ranks = kDefaultCryptomatteRanks;
  bool any() const { return object || material; }
  // The types asked for, object first.
  std::vector<CryptomatteType> types() const;
  // "object,material ranks=6", or "off": the header's record.
  std::string describe() const;
};
// Parses a comma-separated list of `object`, `material` (or `none`) and a
// rank count in [1, kMaxCryptomatteRanks]; throws obscura::Error naming the
// option (--cryptomatte / --cryptomatte-ranks) and what is wrong.
CryptomatteSettings parseCryptomatte(const std::string& list, int ranks);
// Throws that error for a rank count out of range.
void checkCryptomatteRanks(int ranks);

// The names ids are made of. Object: its name (core/scene/objects.h; "unnamed"
// for geometry that belongs to no object). Material: the glTF material's
// name, "materials[i]" when it has none, "default" for the default
// material of primitives without one (and OBJ cages).
std::string cryptomatteObjectName(const Scene& scene, uint32_t object);
std::string cryptomatteMaterialName(const Scene& scene, int material);
// The manifest of one type: every name the scene has for it (whether seen
// or not), as JSON {name: hex}.
std::string cryptomatteManifest(const Scene& scene, CryptomatteType type);
// Appends the cryptomatte/<key>/... attributes of every type asked for and
// obscura:cryptomatte (the settings), and keeps the layers 32-bit under
// --half (a half float cannot hold an id).
void addCryptomatteHeader(const Scene& scene, const CryptomatteSettings& s, ExrOptions& exr);
// Bytes the planes take on a w x h film.
uint64_t cryptomatteBytes(const CryptomatteSettings& s, int width, int height);

// The screen-space loop's Cryptomatte (its G-buffer layers hold one sample
// of every pixel, so a pixel's samples never meet there): the camera rays
// of the ray-traced loop once more, pixel-major, into `crypto` (parallel over
// tiles; the caller's TBB arena). Counts the rays into `cameraRays`.
struct RenderSettings;
struct Camera;
class Tracer;
class CryptomatteFilm;
void renderCryptomatteSamples(const Scene& scene, const Tracer& tracer, const Camera& camera, const RenderSettings& s,
                              const CryptomatteFilm& crypto, uint64_t& cameraRays);

// One render's Cryptomatte planes and the id tables they are filled from.
// The render loop walks each tile's camera samples pixel-major, sample-minor
// and reports every hit in that order (addHit); the tile's scratch counts
// the ids of the pixel in progress and writes its ranks into the film when
// the next pixel starts (or the tile ends), so nothing is kept per sample.
class CryptomatteFilm {
 public:
  // Adds the planes (`<Type>NN.R/G/B/A`, object layers first) to `film`.
  CryptomatteFilm(const Scene& scene, const CryptomatteSettings& s, int spp, Film& film);

  // Per-thread scratch: the id counts of the pixel in progress.
  struct Tile {
    PixelRect rect;
    uint32_t pixel = ~0u;  // within rect, row-major; ~0u = none yet
    std::vector<std::pair<uint32_t, uint32_t>> counts[2];  // (id bits, samples) per type
  };
  void beginTile(const PixelRect& r, Tile& t) const;
  // A camera sample of pixel `pixel` (within the tile; non-decreasing
  // across calls) that saw object `object` (not a holdout) at Embree ids
  // geomID / instID.
  void addHit(Tile& t, uint32_t pixel, uint32_t object, unsigned geomID, unsigned instID) const;
  void addHit(Tile& t, uint32_t pixel, const SurfaceHit& h) const;
  // Writes the last pixel's ranks.
  void endTile(Tile& t) const;

 private:
  void flush(Tile& t) const;
  const Scene& scene_;
  Film& film_;
  int ranks_, spp_;
  std::vector<CryptomatteType> types_;
  std::vector<int> planes_[2];  // per entry of types_: <Type>00.R, .G, .B, .A, <Type>01.R, ...
  std::vector<uint32_t> objectIds_;    // per object, then one for kNoObject
  std::vector<uint32_t> materialIds_;  // per material + 1: [0] = default material
};

}  // namespace obscura
