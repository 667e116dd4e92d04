// Cryptomatte (core/render/cryptomatte.h, docs/exr.md "Cryptomatte"): the hash and id
// conversion against published values, the manifest, and rendered files
// decoded pixel by pixel back to the objects and materials the test placed.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>

#include "core/render/cryptomatte.h"
#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// MurmurHash3_x86_32 test vectors: the seed-0 values from the SMHasher
// reference implementation's outputs as widely tabulated (e.g. "hello" =
// 0x248bfa47), and seeded ones covering every tail length (0-3 bytes).
TEST(Cryptomatte, MurmurHash3MatchesPublishedVectors) {
  EXPECT_EQ(murmurHash3_x86_32("", 0), 0u);
  EXPECT_EQ(murmurHash3_x86_32("", 1), 0x514e28b7u);
  EXPECT_EQ(murmurHash3_x86_32("", 0xffffffffu), 0x81f16f39u);
  EXPECT_EQ(murmurHash3_x86_32(std::string_view("\0\0\0\0", 4), 0), 0x2362f9deu);
  EXPECT_EQ(murmurHash3_x86_32("aaaa", 0x9747b28cu), 0x5a97808au);
  EXPECT_EQ(murmurHash3_x86_32("aaa", 0x9747b28cu), 0x283e0130u);
  EXPECT_EQ(murmurHash3_x86_32("aa", 0x9747b28cu), 0x5d211726u);
  EXPECT_EQ(murmurHash3_x86_32("a", 0x9747b28cu), 0x7fa09ea6u);
  EXPECT_EQ(murmurHash3_x86_32("Hello, world!", 0x9747b28cu), 0x24884cbau);
  EXPECT_EQ(murmurHash3_x86_32("The quick brown fox jumps over the lazy dog", 0x9747b28cu), 0x2fa826cdu);
  EXPECT_EQ(murmurHash3_x86_32("hello", 0), 0x248bfa47u);
  EXPECT_EQ(murmurHash3_x86_32("a", 0), 0x3c2569b2u);
}

// The specification's own examples (Psyop Cryptomatte specification,
// "Metadata" and "Manifest"): the manifest entries of "bunny", "default"
// and "bunny_porcelain_mat". The metadata key is the first 7 hex digits of
// the type name's id (the reference Nuke plugin's layer_hash; the keys in
// the specification's text are placeholders, not hashes of the names
// beside them): these values come from a separate Python transcription of
// the algorithm, which reproduces the manifest examples above.
TEST(Cryptomatte, SpecificationExamples) {
  EXPECT_EQ(cryptomatteHex(cryptomatteNameId("bunny")), "13851a76");
  EXPECT_EQ(cryptomatteHex(cryptomatteNameId("default")), "42c9679f");
  EXPECT_EQ(cryptomatteHex(cryptomatteNameId("bunny_porcelain_mat")), "b24b26d4");
  EXPECT_EQ(cryptomatteKey("CryptoObject"), "3ae39a5");
  EXPECT_EQ(cryptomatteKey("CryptoMaterial"), "be359d6");
  // As a float (the pixel value), the spec's manifest example decodes to
  // the id the manifest's hex names.
  EXPECT_EQ(floatToBits(bitsToFloat(cryptomatteNameId("bunny"))), 0x13851a76u);
}

// The exponent rule: a hash whose 8 exponent bits are all 0 or all 1 gets
// its lowest exponent bit flipped (= clamping the exponent to [1, 254]);
// every other hash is its own id. Every id is then a finite normal float.
TEST(Cryptomatte, ExponentRule) {
  EXPECT_EQ(cryptomatteIdBits(0x00000000u), 0x00800000u);  // +0
  EXPECT_EQ(cryptomatteIdBits(0x00000001u), 0x00800001u);  // denormal
  EXPECT_EQ(cryptomatteIdBits(0x807fffffu), 0x80ffffffu);  // negative denormal
  EXPECT_EQ(cryptomatteIdBits(0x7f800000u), 0x7f000000u);  // +inf
  EXPECT_EQ(cryptomatteIdBits(0xffc00001u), 0xff400001u);  // NaN
  EXPECT_EQ(cryptomatteIdBits(0x3f800000u), 0x3f800000u);  // 1.0: unchanged
  EXPECT_EQ(cryptomatteIdBits(0x00800000u), 0x00800000u);  // smallest normal: unchanged
  EXPECT_EQ(cryptomatteIdBits(0x7f7fffffu), 0x7f7fffffu);  // largest finite: unchanged
  for (uint32_t e = 0; e < 256; ++e) {
    const uint32_t h = (e << 23) | 0x2345u | (e & 1u) << 31;
    const uint32_t clamped = std::min(std::max(e, 1u), 254u);
    EXPECT_EQ((cryptomatteIdBits(h) >> 23) & 0xffu, clamped);
    EXPECT_EQ(cryptomatteIdBits(h) & ~(0xffu << 23), h & ~(0xffu << 23));  // sign and mantissa kept
    EXPECT_TRUE(std::isnormal(bitsToFloat(cryptomatteIdBits(h))));
  }
  EXPECT_EQ(floatToBits(bitsToFloat(0x13851a76u)), 0x13851a76u);
}

TEST(Cryptomatte, SettingsParseAndRefuse) {
  const CryptomatteSettings both = parseCryptomatte("object,material", 6);
  EXPECT_TRUE(both.object && both.material);
  EXPECT_EQ(both.describe(), "object,material ranks=6");
  EXPECT_EQ(parseCryptomatte("material", 1).describe(), "material ranks=1");
  EXPECT_FALSE(parseCryptomatte("none", 6).any());
  EXPECT_EQ(parseCryptomatte("none", 6).describe(), "off");
  EXPECT_EQ(parseCryptomatte("object", kMaxCryptomatteRanks).ranks, kMaxCryptomatteRanks);
  const auto refused = [](const std::string& list, int ranks, const std::string& needle) {
    try {
      parseCryptomatte(list, ranks);
      ADD_FAILURE() << list << " " << ranks << " was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  refused("objects", 6, "--cryptomatte: 'objects'");
  refused("object,", 6, "--cryptomatte: ''");
  refused("", 6, "--cryptomatte");
  refused("none,object", 6, "--cryptomatte: 'none'");
  refused("object", 0, "--cryptomatte-ranks: must be in [1, 32], got 0");
  refused("object", -3, "--cryptomatte-ranks");
  refused("object", kMaxCryptomatteRanks + 1, "--cryptomatte-ranks: must be in [1, 32], got 33");
}

// --- a rendered scene ---------------------------------------------------------

// 64 x 32 pixels, yfov with tan(yfov / 2) = 1/2: a point (x, y, z), z < 0,
// lands at film position (32 + 32 x / -z, 16 - 32 y / -z) (pixels, y down).
constexpr int kW = 64, kH = 32;
constexpr double kScale = 32.0;

// A square of half-size h facing the camera at depth -z, centred on (cx, cy).
struct Square {
  std::string node;      // "" = unnamed node
  std::string mesh;      // the mesh's name ("" = none)
  std::string material;  // the material's name, "" = unnamed material, "-" = none
  double cx, cy, z, h;
  json roles = nullptr;  // extras.obscura
  std::string idName;    // the name the ids should carry
  std::string materialIdName;
  // Its film rectangle.
  double x0() const { return 32 + kScale * (cx - h) / -z; }
  double x1() const { return 32 + kScale * (cx + h) / -z; }
  double y0() const { return 16 - kScale * (cy + h) / -z; }
  double y1() const { return 16 - kScale * (cy - h) / -z; }
  bool covers(int px, int py) const { return x0() <= px && px + 1 <= x1() && y0() <= py && py + 1 <= y1(); }
  bool overlaps(int px, int py) const { return x0() < px + 1 && px < x1() && y0() < py + 1 && py < y1(); }
};

// Objects side by side with edges off the pixel grid (partly covered
// pixels), one in front of two others (pixels with several ids), a matte
// holdout and a camera-invisible object in front of others, materials
// named, unnamed, shared and absent, a node named only by its mesh.
std::vector<Square> squares() {
  return {
      {"left", "", "red", -2.5, 0.0, -4.0, 1.03, nullptr, "left", "red"},
      {"mid", "", "", 0.0, 0.0, -4.0, 1.03, nullptr, "mid", "materials[1]"},
      {"", "meshy", "-", 2.5, 0.0, -4.0, 1.03, nullptr, "meshy", "default"},
      {"front", "", "red", -1.2, 0.6, -3.0, 0.5, nullptr, "front", "red"},
      {"hold", "", "-", 0.5, -0.8, -3.5, 0.3, {{"matte", true}}, "", ""},
      {"ghost", "", "-", 2.5, 0.0, -3.0, 0.4, {{"camera", false}}, "", ""},
  };
}

std::string writeScene(const std::string& dir) {
  GltfBuilder g;
  std::vector<int> roots;
  std::map<std::string, int> materials;
  for (const Square& s : squares()) {
    int mat = -1;
    if (s.material != "-") {
      if (!materials.count(s.material)) {
        json m = {{"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1}}}}};
        if (!s.material.empty()) m["name"] = s.material;
        materials[s.material] = g.push("materials", m);
      }
      mat = materials[s.material];
    }
    const int mesh = g.quadMesh(float(s.h), mat);
    if (!s.mesh.empty()) g.doc["meshes"][size_t(mesh)]["name"] = s.mesh;
    json node = {{"mesh", mesh}, {"translation", {s.cx, s.cy, s.z}}};
    if (!s.node.empty()) node["name"] = s.node;
    if (!s.roles.is_null()) node["extras"] = {{"obscura", s.roles}};
    roots.push_back(g.node(node));
  }
  g.push("cameras", perspective("cam", 2.0 * std::atan(0.5), 0.1));
  roots.push_back(g.node({{"name", "cam"}, {"camera", 0}}));
  g.scene(roots);
  return g.writeGltf(dir, "crypto");
}

// A decoded pixel: (id bits, coverage) per rank present.
using Ranks = std::vector<std::pair<uint32_t, float>>;

struct Decoded {
  std::map<std::string, uint32_t> manifest;  // name -> id bits
  std::map<uint32_t, std::string> names;     // id bits -> name
  int layers = 0;
  std::vector<Ranks> pixels;
};

// Reads type `name` of a file back as a compositor would: the header's
// key, manifest and the `<name>NN` layers.
Decoded decode(const ReadBack& rb, const std::string& name, int ranks) {
  Decoded d;
  const std::string key = cryptomatteKey(name);
  const std::string prefix = "cryptomatte/" + key + "/";
  EXPECT_EQ(rb.spec.get_string_attribute(prefix + "name"), name);
  EXPECT_EQ(rb.spec.get_string_attribute(prefix + "hash"), "MurmurHash3_32");
  EXPECT_EQ(rb.spec.get_string_attribute(prefix + "conversion"), "uint32_to_float32");
  const auto manifest = nlohmann::json::parse(rb.spec.get_string_attribute(prefix + "manifest"));
  EXPECT_TRUE(manifest.is_object());
  for (const auto& [n, hex] : manifest.items()) {
    const std::string h = hex.get<std::string>();
    EXPECT_EQ(h.size(), 8u) << n;
    const uint32_t bits = uint32_t(std::stoul(h, nullptr, 16));
    EXPECT_EQ(bits, cryptomatteNameId(n)) << n;
    d.manifest[n] = bits;
    d.names[bits] = n;
  }
  char layer[64];
  while (true) {
    std::snprintf(layer, sizeof layer, "%s%02d.R", name.c_str(), d.layers);
    if (!rb.planes.count(layer)) break;
    ++d.layers;
  }
  EXPECT_EQ(d.layers, (ranks + 1) / 2);
  d.pixels.resize(size_t(kW) * kH);
  for (int l = 0; l < d.layers; ++l) {
    std::string base = name + (l < 10 ? "0" : "") + std::to_string(l);
    const auto& R = rb.planes.at(base + ".R");
    const auto& G = rb.planes.at(base + ".G");
    const auto& B = rb.planes.at(base + ".B");
    const auto& A = rb.planes.at(base + ".A");
    for (size_t i = 0; i < d.pixels.size(); ++i) {
      if (G[i] > 0) d.pixels[i].push_back({floatToBits(R[i]), G[i]});
      else EXPECT_EQ(R[i], 0.0f);
      if (B[i] != 0 || A[i] != 0) {
        EXPECT_LT(2 * l + 1, ranks) << "a rank beyond --cryptomatte-ranks";
        if (A[i] > 0) d.pixels[i].push_back({floatToBits(B[i]), A[i]});
      }
    }
  }
  return d;
}

// Every pixel of a decoded type against the scene: the ranks are sorted
// (coverage descending, ties by id bits), each coverage a whole number of
// samples, their sum the pixel's alpha (all of it when every id fits in
// the ranks); every id in the manifest, naming an object whose square
// overlaps the pixel; pixels wholly inside one visible square (nothing in
// front) are that square's with coverage 1, pixels wholly inside the
// matte in front have nothing.
void checkDecoded(const Decoded& d, const std::vector<float>& alpha, int spp, int ranks, bool material) {
  const std::vector<Square> sq = squares();
  size_t whole = 0, several = 0, holdout = 0;
  for (int py = 0; py < kH; ++py)
    for (int px = 0; px < kW; ++px) {
      const size_t i = size_t(py) * kW + size_t(px);
      const Ranks& r = d.pixels[i];
      double sum = 0;
      for (size_t k = 0; k < r.size(); ++k) {
        const auto [bits, cov] = r[k];
        sum += cov;
        // Coverage = count / spp exactly up to float rounding of the quotient.
        const double count = double(cov) * spp;
        EXPECT_NEAR(count, std::round(count), 1e-4) << px << "," << py;
        if (k > 0) {
          EXPECT_TRUE(r[k - 1].second > cov || (r[k - 1].second == cov && r[k - 1].first < bits)) << px << "," << py;
        }
        ASSERT_TRUE(d.names.count(bits)) << "id " << cryptomatteHex(bits) << " at " << px << "," << py << " not in the manifest";
        const std::string& name = d.names.at(bits);
        bool placed = false;
        for (const Square& s : sq)
          if (!s.idName.empty() && (material ? s.materialIdName : s.idName) == name && s.overlaps(px, py)) placed = true;
        EXPECT_TRUE(placed) << name << " at " << px << "," << py;
      }
      // Every id fits: the coverages sum to alpha (float rounding of count / spp).
      if (int(r.size()) < ranks) EXPECT_NEAR(sum, alpha[i], 1e-6) << px << "," << py;
      else EXPECT_LE(sum, alpha[i] + 1e-6) << px << "," << py;
      // A pixel wholly inside a square with nothing nearer overlapping it.
      for (const Square& s : sq) {
        if (!s.covers(px, py)) continue;
        bool nearer = false;
        for (const Square& o : sq)
          if (o.z > s.z && o.overlaps(px, py) && o.roles.is_null()) nearer = true;
        if (nearer) continue;
        if (s.node == "hold") {
          EXPECT_TRUE(r.empty()) << "holdout at " << px << "," << py;
          EXPECT_EQ(alpha[i], 0.0f);
          ++holdout;
        } else if (!s.idName.empty()) {
          bool hidden = false;  // a matte in front
          for (const Square& o : sq)
            if (o.node == "hold" && o.z > s.z && o.overlaps(px, py)) hidden = true;
          if (hidden) continue;
          ASSERT_FALSE(r.empty()) << px << "," << py;
          EXPECT_EQ(d.names.at(r[0].first), material ? s.materialIdName : s.idName) << px << "," << py;
          EXPECT_EQ(r[0].second, 1.0f) << px << "," << py;
          ++whole;
        }
      }
      if (r.size() > 1) ++several;
    }
  // The layout has all three kinds of pixels (else the test tests
  // nothing): floors well below the counts this layout gives at 16 spp
  // (774 whole pixels, the holdout's 5 x 5; several ids in 22 pixels
  // along overlapping edges, in 8 for materials, as two objects share
  // "red").
  EXPECT_GT(whole, 200u);
  EXPECT_GT(holdout, 4u);
  if (ranks > 1) EXPECT_GT(several, 4u);
}

struct Rendered {
  CliResult cli;
  ReadBack rb;
};

TEST(Cryptomatte, RenderedLayersDecodeToTheScene) {
  const std::string dir = tempDir("cryptomatte_render");
  const std::string scene = writeScene(dir);
  const int spp = 16;
  const auto args = [&](const std::string& out, std::vector<std::string> extra) {
    std::vector<std::string> a = {"render", scene, "-o", dir + "/" + out, "--res", "64x32", "--spp", std::to_string(spp), "-q"};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  const std::vector<int> rankCounts = {6, 1, 3, 32};
  std::vector<std::vector<std::string>> runs;
  for (int r : rankCounts)
    runs.push_back(args("r" + std::to_string(r) + ".exr", {"--cryptomatte", "object,material", "--cryptomatte-ranks", std::to_string(r)}));
  runs.push_back(args("half.exr", {"--cryptomatte", "object", "--half"}));
  runs.push_back(args("vo.exr", {"--cryptomatte", "object,material", "-i", "vo"}));
  runs.push_back(args("plain.exr", {}));
  const auto results = runClis(runs, dir);
  for (const CliResult& r : results) ASSERT_EQ(r.exitCode, 0) << r.stderrText;

  // The scene's names, as the loader gives them.
  const auto loaded = loadGltf(scene);
  std::set<std::string> objects;
  for (const SceneObject& o : loaded->objects) objects.insert(o.name);
  EXPECT_TRUE(objects.count("meshy"));  // an unnamed node: its mesh's name

  for (size_t k = 0; k < rankCounts.size(); ++k) {
    const int ranks = rankCounts[k];
    SCOPED_TRACE("ranks " + std::to_string(ranks));
    const ReadBack rb = readExr(dir + "/r" + std::to_string(ranks) + ".exr");
    ASSERT_TRUE(rb.ok);
    EXPECT_EQ(rb.spec.get_string_attribute("obscura:cryptomatte"), "object,material ranks=" + std::to_string(ranks));
    const std::vector<float>& alpha = rb.planes.at("A");
    const Decoded obj = decode(rb, kCryptoObject, ranks);
    const Decoded mat = decode(rb, kCryptoMaterial, ranks);
    // The manifests name every object and material of the scene.
    for (const std::string& o : objects) EXPECT_TRUE(obj.manifest.count(o)) << o;
    for (const char* m : {"red", "materials[1]", "default"}) EXPECT_TRUE(mat.manifest.count(m)) << m;
    checkDecoded(obj, alpha, spp, ranks, false);
    checkDecoded(mat, alpha, spp, ranks, true);
    // Fewer ranks keep the leading ranks of more (the same samples, the
    // same order): every pixel's ranks are a prefix of the 32-rank file's.
    if (ranks != 32) {
      const Decoded most = decode(readExr(dir + "/r32.exr"), kCryptoObject, 32);
      for (size_t i = 0; i < obj.pixels.size(); ++i) {
        ASSERT_LE(obj.pixels[i].size(), most.pixels[i].size());
        for (size_t j = 0; j < obj.pixels[i].size(); ++j) EXPECT_EQ(obj.pixels[i][j], most.pixels[i][j]) << i;
      }
    }
  }

  // --half keeps the ids' bits (32-bit layers) and rounds the rest.
  const ReadBack half = readExr(dir + "/half.exr");
  const ReadBack full = readExr(dir + "/r6.exr");
  ASSERT_TRUE(half.ok && full.ok);
  for (const char* c : {"CryptoObject00.R", "CryptoObject00.G", "CryptoObject01.B", "CryptoObject02.A"})
    EXPECT_EQ(half.planes.at(c), full.planes.at(c)) << c;
  EXPECT_EQ(half.planes.count("CryptoMaterial00.R"), 0u);
  // 32-bit: the 12 Cryptomatte channels, Z and N.X/Y/Z (docs/exr.md "Depth
  // and camera conventions") and spp (integer counts); the rest is half.
  int formats = 0;
  for (size_t c = 0; c < half.spec.channelformats.size(); ++c) {
    const std::string& name = half.spec.channelnames[c];
    const bool keep = name.rfind("CryptoObject", 0) == 0 || name == "Z" || name.rfind("N.", 0) == 0 || name == kSppPlane;
    EXPECT_EQ(half.spec.channelformats[c] == OIIO::TypeDesc::FLOAT, keep) << name;
    formats += half.spec.channelformats[c] == OIIO::TypeDesc::FLOAT && name.rfind("Crypto", 0) == 0;
  }
  EXPECT_EQ(formats, 12);

  // A screen-space integrator's render traces the same camera rays for
  // its ids: the same layers, bit for bit.
  const ReadBack vo = readExr(dir + "/vo.exr");
  ASSERT_TRUE(vo.ok);
  size_t layers = 0;
  for (const auto& [n, p] : full.planes)
    if (n.rfind("Crypto", 0) == 0) {
      ++layers;
      ASSERT_TRUE(vo.planes.count(n)) << n;
      EXPECT_EQ(vo.planes.at(n), p) << n;
    }
  EXPECT_EQ(layers, 24u);  // 2 types x 3 layers x RGBA
  EXPECT_EQ(vo.planes.at("A"), full.planes.at("A"));

  // Off by default: no layers, no attributes, the same pass.
  const ReadBack plain = readExr(dir + "/plain.exr");
  ASSERT_TRUE(plain.ok);
  for (const auto& [n, p] : plain.planes) EXPECT_EQ(n.find("Crypto"), std::string::npos) << n;
  EXPECT_EQ(plain.spec.get_string_attribute("cryptomatte/" + cryptomatteKey(kCryptoObject) + "/name"), "");
  EXPECT_EQ(plain.planes.at("R"), full.planes.at("R"));
  EXPECT_EQ(plain.planes.at("A"), full.planes.at("A"));
}

TEST(Cryptomatte, BadOptionsAreRefusedWithOneLine) {
  const std::string dir = tempDir("cryptomatte_bad");
  const std::string scene = writeScene(dir);
  const auto args = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = {"render", scene, "-o", dir + "/out.exr", "--res", "16x8", "--spp", "1", "-q"};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--cryptomatte", "object", "--cryptomatte-ranks", "0"}, "--cryptomatte-ranks: must be in [1, 32], got 0"},
      {{"--cryptomatte", "object", "--cryptomatte-ranks", "33"}, "--cryptomatte-ranks: must be in [1, 32], got 33"},
      {{"--cryptomatte", "objects"}, "--cryptomatte: 'objects'"},
  };
  std::vector<std::vector<std::string>> runs;
  for (const auto& c : cases) runs.push_back(args(c.first));
  const auto results = runClis(runs, dir);
  for (size_t i = 0; i < cases.size(); ++i) {
    EXPECT_EQ(results[i].exitCode, 1) << results[i].stderrText;
    EXPECT_NE(results[i].stderrText.find("obscura: error: " + cases[i].second), std::string::npos) << results[i].stderrText;
    EXPECT_EQ(std::count(results[i].stderrText.begin(), results[i].stderrText.end(), '\n'), 1) << results[i].stderrText;
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/out.exr"));
}

}  // namespace
}  // namespace obscura::test
