#include "core/render/cryptomatte.h"

#include <nlohmann/json.hpp>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdio>
#include <cstring>

#include <obscura/error.h>
#include "core/render/gbuffer.h"
#include "core/render/render.h"
#include "core/scene/scene.h"
#include "core/scene/surface.h"

namespace obscura {
namespace {

uint32_t rotl32(uint32_t x, int r) { return (x << r) | (x >> (32 - r)); }

// MurmurHash3's per-block mix of a 32-bit word into the state.
uint32_t mixBlock(uint32_t k) {
  k *= 0xcc9e2d51u;
  k = rotl32(k, 15);
  return k * 0x1b873593u;
}

// Channels per layer and ranks per layer (two id/coverage pairs in RGBA).
constexpr int kLayerChannels = 4;
constexpr const char* kChannelSuffix[kLayerChannels] = {".R", ".G", ".B", ".A"};

int layersFor(int ranks) { return (ranks + 1) / 2; }

}  // namespace

uint32_t murmurHash3_x86_32(std::string_view data, uint32_t seed) {
  const auto* p = reinterpret_cast<const unsigned char*>(data.data());
  const size_t n = data.size();
  uint32_t h = seed;
  // The body: 4-byte little-endian blocks.
  size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    const uint32_t k = uint32_t(p[i]) | uint32_t(p[i + 1]) << 8 | uint32_t(p[i + 2]) << 16 | uint32_t(p[i + 3]) << 24;
    h ^= mixBlock(k);
    h = rotl32(h, 13);
    h = h * 5u + 0xe6546b64u;
  }
  // The 1-3 trailing bytes, little-endian, mixed without the rotate-add.
  uint32_t tail = 0;
  for (size_t j = n - i; j-- > 0;) tail = (tail << 8) | p[i + j];
  if (n - i > 0) h ^= mixBlock(tail);
  // Finalization: the length, then the avalanche.
  h ^= uint32_t(n);
  h ^= h >> 16;
  h *= 0x85ebca6bu;
  h ^= h >> 13;
  h *= 0xc2b2ae35u;
  h ^= h >> 16;
  return h;
}

uint32_t cryptomatteIdBits(uint32_t hash) {
  // Exponent 0 (zero, denormals) or 255 (inf, NaN) would not survive
  // compositing arithmetic; flipping its lowest bit gives 1 or 254 (the
  // spec's clamp to [1, 254] says the same).
  const uint32_t exponent = (hash >> 23) & 0xffu;
  return exponent == 0u || exponent == 0xffu ? hash ^ (1u << 23) : hash;
}

float bitsToFloat(uint32_t bits) {
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

uint32_t floatToBits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return b;
}

std::string cryptomatteHex(uint32_t bits) {
  char s[9];
  std::snprintf(s, sizeof s, "%08x", bits);
  return s;
}

std::string cryptomatteKey(std::string_view layerName) { return cryptomatteHex(cryptomatteNameId(layerName)).substr(0, 7); }

std::vector<CryptomatteType> CryptomatteSettings::types() const {
  std::vector<CryptomatteType> t;
  if (object) t.push_back(CryptomatteType::Object);
  if (material) t.push_back(CryptomatteType::Material);
  return t;
}

std::string CryptomatteSettings::describe() const {
  if (!any()) return "off";
  std::string s = object && material ? "object,material" : object ? "object" : "material";
  return s + " ranks=" + std::to_string(ranks);
}

CryptomatteSettings parseCryptomatte(const std::string& list, int ranks) {
  CryptomatteSettings s;
  size_t start = 0;
  while (start <= list.size()) {
    const size_t comma = std::min(list.find(',', start), list.size());
    const std::string item = list.substr(start, comma - start);
    if (item == "object") s.object = true;
    else if (item == "material") s.material = true;
    else if (item != "none" || list != "none")
      throw Error("--cryptomatte: '" + item + "' in '" + list + "': expected object, material or both (object,material), or none");
    start = comma + 1;
  }
  checkCryptomatteRanks(ranks);
  s.ranks = ranks;
  return s;
}

void checkCryptomatteRanks(int ranks) {
  if (ranks < 1 || ranks > kMaxCryptomatteRanks)
    throw Error("--cryptomatte-ranks: must be in [1, " + std::to_string(kMaxCryptomatteRanks) + "], got " + std::to_string(ranks));
}

std::string cryptomatteObjectName(const Scene& scene, uint32_t object) {
  return object < scene.objects.size() ? scene.objects[object].name : "unnamed";
}

std::string cryptomatteMaterialName(const Scene& scene, int material) {
  if (material < 0 || size_t(material) >= scene.materials.size()) return "default";
  const std::string& n = scene.materials[size_t(material)].name;
  return n.empty() ? "materials[" + std::to_string(material) + "]" : n;
}

std::string cryptomatteManifest(const Scene& scene, CryptomatteType type) {
  nlohmann::json m = nlohmann::json::object();
  const auto add = [&](const std::string& name) { m[name] = cryptomatteHex(cryptomatteNameId(name)); };
  if (type == CryptomatteType::Object) {
    for (uint32_t o = 0; o < scene.objects.size(); ++o) add(cryptomatteObjectName(scene, o));
    if (scene.objects.empty()) add(cryptomatteObjectName(scene, kNoObject));
  } else {
    add(cryptomatteMaterialName(scene, -1));
    for (size_t i = 0; i < scene.materials.size(); ++i) add(cryptomatteMaterialName(scene, int(i)));
  }
  return m.dump();
}

void addCryptomatteHeader(const Scene& scene, const CryptomatteSettings& s, ExrOptions& exr) {
  std::vector<HeaderAttribute>& attributes = exr.attributes;
  attributes.push_back({"obscura:cryptomatte", s.describe()});
  for (const CryptomatteType t : s.types()) {
    const std::string name = cryptomatteLayerName(t);
    exr.floatChannelPrefixes.push_back(name);
    const std::string prefix = "cryptomatte/" + cryptomatteKey(name) + "/";
    attributes.push_back({prefix + "name", name});
    attributes.push_back({prefix + "hash", std::string("MurmurHash3_32")});
    attributes.push_back({prefix + "conversion", std::string("uint32_to_float32")});
    attributes.push_back({prefix + "manifest", cryptomatteManifest(scene, t)});
  }
}

uint64_t cryptomatteBytes(const CryptomatteSettings& s, int width, int height) {
  return uint64_t(s.types().size()) * uint64_t(layersFor(s.ranks)) * kLayerChannels * sizeof(float) * uint64_t(width) *
         uint64_t(height);
}

CryptomatteFilm::CryptomatteFilm(const Scene& scene, const CryptomatteSettings& s, int spp, Film& film)
    : scene_(scene), film_(film), ranks_(s.ranks), spp_(spp), types_(s.types()) {
  for (size_t k = 0; k < types_.size(); ++k) {
    for (int layer = 0; layer < layersFor(ranks_); ++layer) {
      char n[16];  // room for any int, so the compiler sees no truncation
      std::snprintf(n, sizeof n, "%02d", layer);
      for (const char* c : kChannelSuffix) {
        planes_[k].push_back(film.addPlane(std::string(cryptomatteLayerName(types_[k])) + n + c));
      }
    }
  }
  // Hashed once: the loop only looks ids up.
  for (uint32_t o = 0; o < scene.objects.size(); ++o) objectIds_.push_back(cryptomatteNameId(cryptomatteObjectName(scene, o)));
  objectIds_.push_back(cryptomatteNameId(cryptomatteObjectName(scene, kNoObject)));
  for (int m = -1; m < int(scene.materials.size()); ++m) materialIds_.push_back(cryptomatteNameId(cryptomatteMaterialName(scene, m)));
}

void CryptomatteFilm::beginTile(const PixelRect& r, Tile& t) const {
  t.rect = r;
  t.pixel = ~0u;
  for (auto& c : t.counts) c.clear();
}

void CryptomatteFilm::addHit(Tile& t, uint32_t pixel, const SurfaceHit& h) const {
  addHit(t, pixel, h.object, h.geomID, h.instID);
}

void CryptomatteFilm::addHit(Tile& t, uint32_t pixel, uint32_t object, unsigned geomID, unsigned instID) const {
  if (pixel != t.pixel) {
    flush(t);
    t.pixel = pixel;
  }
  for (size_t k = 0; k < types_.size(); ++k) {
    uint32_t id;
    if (types_[k] == CryptomatteType::Object) {
      id = objectIds_[std::min<size_t>(object, objectIds_.size() - 1)];
    } else {
      const Affine* toWorld;
      const int m = scene_.primitiveOf(geomID, instID, &toWorld).material;
      id = materialIds_[size_t(m + 1)];
    }
    // A pixel sees a handful of ids: a linear search beats any map. The
    // vector keeps its capacity across pixels and tiles (amortized).
    auto& counts = t.counts[k];
    auto it = std::find_if(counts.begin(), counts.end(), [id](const auto& e) { return e.first == id; });
    if (it != counts.end()) ++it->second;
    else counts.emplace_back(id, 1u);
  }
}

void CryptomatteFilm::endTile(Tile& t) const {
  flush(t);
  t.pixel = ~0u;
}

void CryptomatteFilm::flush(Tile& t) const {
  if (t.pixel == ~0u) return;
  const int w = t.rect.width();
  const int x = t.rect.x0 + int(t.pixel % uint32_t(w)), y = t.rect.y0 + int(t.pixel / uint32_t(w));
  for (size_t k = 0; k < types_.size(); ++k) {
    auto& counts = t.counts[k];
    // Most samples first; equal counts by id bits (deterministic).
    std::sort(counts.begin(), counts.end(),
              [](const auto& a, const auto& b) { return a.second != b.second ? a.second > b.second : a.first < b.first; });
    const size_t n = std::min(counts.size(), size_t(ranks_));
    for (size_t r = 0; r < n; ++r) {
      // Layer r / 2, R and G (even r) or B and A (odd r): planes 2r, 2r + 1.
      film_.at(planes_[k][2 * r], x, y) = bitsToFloat(counts[r].first);
      film_.at(planes_[k][2 * r + 1], x, y) = float(double(counts[r].second) / double(spp_));
    }
    counts.clear();
  }
}

void renderCryptomatteSamples(const Scene& scene, const Tracer& tracer, const Camera& camera, const RenderSettings& s,
                              const CryptomatteFilm& crypto, uint64_t& cameraRays) {
  constexpr size_t kChunk = 256;  // camera rays per traced stream, as in the render loops
  const RasterCamera raster(camera, s.width, s.height);
  const Sampler sampler(s.seed);
  const bool mattes = scene.hasMattes();
  struct Scratch {
    IntersectBatch rays;
    CryptomatteFilm::Tile tile;
    uint32_t lanePixel[kChunk];
    uint64_t count = 0;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  const uint32_t spp = uint32_t(s.spp);
  tbb::parallel_for(tbb::blocked_range<int>(0, PixelRect::tileCount(s.tileSize, s.width, s.height), 1),
                    [&](const tbb::blocked_range<int>& range) {
    Scratch& sc = scratch.local();
    sc.rays.reserve(kChunk);
    for (int t = range.begin(); t != range.end(); ++t) {
      const PixelRect r = PixelRect::tile(t, s.tileSize, s.width, s.height);
      crypto.beginTile(r, sc.tile);
      // The ray-traced loop's walk: pixel-major, sample-minor, each sample
      // the same camera ray (key, filter dimension, film position).
      uint32_t pix = 0, si = 0;
      int px = r.x0, py = r.y0;
      uint32_t key = sampler.pixelKey(uint32_t(px), uint32_t(py));
      const uint64_t total = uint64_t(r.size()) * spp;
      for (uint64_t begin = 0; begin < total; begin += kChunk) {
        const size_t n = size_t(std::min<uint64_t>(kChunk, total - begin));
        sc.rays.clear();
        for (size_t l = 0; l < n; ++l) {
          float fx, fy;
          const SampleStream st = sampleStream(key, si);  // the sample's replicate (include/obscura/sampler.h)
          cameraSampleFilm(s.filter, Sampler::seeds2D(st.key, kDimPixelFilter), st.index, px, py, fx, fy);
          sc.rays.pushCamera(raster.org, raster.direction(fx, fy), camera.znear, camera.zfar);
          sc.lanePixel[l] = pix;
          if (++si == spp && ++pix < r.size()) {
            si = 0;
            px = r.x0 + int(pix % uint32_t(r.width())), py = r.y0 + int(pix / uint32_t(r.width()));
            key = sampler.pixelKey(uint32_t(px), uint32_t(py));
          }
        }
        tracer.intersect(sc.rays, RayCoherence::Coherent);
        sc.count += n;
        for (size_t l = 0; l < n; ++l) {
          if (!sc.rays.hit(l)) continue;
          const uint32_t o = scene.objectOf(sc.rays.geomID(l), sc.rays.instID(l));
          if (mattes && scene.isMatte(o)) continue;  // a holdout: no id
          crypto.addHit(sc.tile, sc.lanePixel[l], o, sc.rays.geomID(l), sc.rays.instID(l));
        }
      }
      crypto.endTile(sc.tile);
    }
  });
  for (const Scratch& sc : scratch) cameraRays += sc.count;
}

}  // namespace obscura
