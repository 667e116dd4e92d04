// The hot-loop arithmetic made cheaper for speed (bench/bench_bare.cpp,
// docs/performance.md "The render loop against a bare Embree loop") against
// straightforward references computed here: the bit
// reversals of the sampler against a bit-by-bit loop, and the concentric
// map's octant sin/cos against the C library's std::sin/std::cos of the
// same angle; the lane (SIMD) forms against the scalar ones.
#include <gtest/gtest.h>
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "core/load/gltf_loader.h"
#include <obscura/math.h>
#include <obscura/sampler.h>
#include "core/scene/surface.h"
#include "core/image/texture.h"
#include <obscura/warp.h>
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

uint32_t reverseReference(uint32_t x) {
  uint32_t r = 0;
  for (int b = 0; b < 32; ++b) r |= ((x >> b) & 1U) << (31 - b);
  return r;
}

TEST(FastPaths, BitReversalsMatchABitLoop) {
  uint32_t x = 0x12345678U;
  for (int i = 0; i < (1 << 16); ++i) {
    x = mixBits32(x + uint32_t(i));
    const uint32_t y = mixBits32(x ^ 0xdeadbeefU);
    ASSERT_EQ(reverseBits32(x), reverseReference(x)) << x;
    const uint64_t both = reverseBits32x2(uint64_t(x) | uint64_t(y) << 32);
    ASSERT_EQ(uint32_t(both), reverseReference(x)) << x;
    ASSERT_EQ(uint32_t(both >> 32), reverseReference(y)) << y;
  }
  for (uint32_t e : {0U, 1U, 0x80000000U, 0xffffffffU}) EXPECT_EQ(reverseBits32(e), reverseReference(e));
}

// The concentric map of Shirley and Chiu written with the library's trig
// (the form the renderer used before): the polynomial octant sin/cos may
// differ from it by float rounding only. A point of the unit disk has
// coordinates of magnitude <= 1, so an absolute bound of a few float ulps
// of 1 (2^-23 = 1.2e-7) is the whole allowance.
void concentricReference(double u, double v, double& x, double& y) {
  const double a = 2 * u - 1, b = 2 * v - 1;
  if (a == 0 && b == 0) {
    x = y = 0;
    return;
  }
  const double r = std::abs(a) > std::abs(b) ? a : b;
  const double phi = std::abs(a) > std::abs(b) ? M_PI / 4 * (b / a) : M_PI / 2 - M_PI / 4 * (a / b);
  x = r * std::cos(phi);
  y = r * std::sin(phi);
}

TEST(FastPaths, ConcentricMapMatchesTheTrigForm) {
  const uint32_t key = Sampler(7).pixelKey(3, 4);
  double worst = 0;
  const auto check = [&](float u, float v) {
    float x, y;
    squareToConcentricDisk(u, v, x, y);
    double rx, ry;
    concentricReference(u, v, rx, ry);
    worst = std::max(worst, std::max(std::abs(x - rx), std::abs(y - ry)));
    ASSERT_LE(double(x) * x + double(y) * y, 1.0 + 4e-7) << u << " " << v;
  };
  for (uint32_t i = 0; i < (1U << 18); ++i) {
    const Sample2 s = Sampler::get2D(key, i, kFirstIntegratorDim);
    check(s.u, s.v);
  }
  // The centre, the diagonals (|a| = |b|: the second branch) and the edges.
  for (float u : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f - 0x1p-24f})
    for (float v : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f - 0x1p-24f}) check(u, v);
  float cx, cy;
  squareToConcentricDisk(0.5f, 0.5f, cx, cy);
  EXPECT_EQ(cx, 0.0f);
  EXPECT_EQ(cy, 0.0f);
  EXPECT_LE(worst, 3.0 * 0x1p-23) << "largest deviation from the trig form";
}

// The lane form of the cosine cone warp (SSE, four lanes at a time) equals
// the scalar warp bit for bit: on sampler points, on the centre, the
// diagonals and the edges of the square, for the hemisphere and a cone, and
// for lane counts that leave a scalar remainder.
TEST(FastPaths, CosineConeLanesEqualTheScalarWarp) {
  const uint32_t key = Sampler(11).pixelKey(5, 9);
  std::vector<float> u, v;
  for (uint32_t i = 0; i < 4096; ++i) {
    const Sample2 s = Sampler::get2D(key, i, kFirstIntegratorDim);
    u.push_back(s.u), v.push_back(s.v);
  }
  for (float a : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f - 0x1p-24f})
    for (float b : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f - 0x1p-24f}) u.push_back(a), v.push_back(b);
  u.push_back(0.5f), v.push_back(0.5f);  // a remainder of 2 lanes
  for (float sinThetaMax : {1.0f, std::sin(0.3f * 1.5707964f)})
    for (size_t n : {u.size(), size_t(3), size_t(0)}) {
      std::vector<float> x(n), y(n), z(n);
      squareToCosineConeLanes(u.data(), v.data(), sinThetaMax, n, x.data(), y.data(), z.data());
      for (size_t l = 0; l < n; ++l) {
        const Vec3 w = squareToCosineCone(u[l], v[l], sinThetaMax);
        ASSERT_EQ(x[l], w.x) << u[l] << " " << v[l];
        ASSERT_EQ(y[l], w.y) << u[l] << " " << v[l];
        ASSERT_EQ(z[l], w.z) << u[l] << " " << v[l];
      }
    }
}


// The lane form of the surface hits (SSE, four hits at a time) equals the
// scalar computeSurfaceHit bit for bit, field by field: on hits traced into
// a scene with vertex normals (one of them zero, so the fallback to Ng
// runs), a mesh without normals, instances (one mirrored, whose cofactor
// normal flips) and, when present, the textured viking room (albedo on);
// then on the same hits with their barycentrics and directions replaced by
// edge cases (u = v = 0, u + v = 1, a zero direction: NaN everywhere, and
// directions of very different lengths), at counts that leave 1-3 lanes.
uint32_t bitsOf(float x) {
  uint32_t b;
  std::memcpy(&b, &x, 4);
  return b;
}

void expectSameHits(const Scene& scene, std::vector<RayHit> rays, bool albedo) {
  ASSERT_GE(rays.size(), 16u);
  // Edge cases on copies of the first hits.
  const size_t traced = rays.size();
  const float uv[][2] = {{0, 0}, {1, 0}, {0, 1}, {0.5f, 0.5f}, {1.0f - 0x1p-24f, 0x1p-24f}};
  const float scale[] = {0.0f, 1e-20f, 3.0f, 1e20f, -2.0f};
  for (size_t i = 0; i < 5; ++i)
    for (size_t j = 0; j < 5; ++j) {
      RayHit r = rays[(i * 5 + j) % traced];
      r.hit.u = uv[i][0], r.hit.v = uv[i][1];
      r.ray.dir_x *= scale[j], r.ray.dir_y *= scale[j], r.ray.dir_z *= scale[j];
      rays.push_back(r);
    }
  std::vector<uint32_t> lanes(rays.size());
  for (size_t i = 0; i < lanes.size(); ++i) lanes[i] = uint32_t(lanes.size() - 1 - i);  // any order
  for (size_t count : {lanes.size(), size_t(1), size_t(2), size_t(3), size_t(6)}) {
    std::vector<SurfaceHit> fast(count), slow(count);
    computeSurfaceHits(scene, rays.data(), lanes.data(), count, albedo, fast.data());
    for (size_t i = 0; i < count; ++i) {
      computeSurfaceHit(scene, rays[lanes[i]], albedo, slow[i]);
      const SurfaceHit &a = fast[i], &b = slow[i];
      SCOPED_TRACE("hit " + std::to_string(i) + " of " + std::to_string(count));
      const auto same3 = [](Vec3 x, Vec3 y) {
        return bitsOf(x.x) == bitsOf(y.x) && bitsOf(x.y) == bitsOf(y.y) && bitsOf(x.z) == bitsOf(y.z);
      };
      ASSERT_TRUE(same3(a.p, b.p)) << "p";
      ASSERT_TRUE(same3(a.ng, b.ng)) << "ng";
      ASSERT_TRUE(same3(a.ns, b.ns)) << "ns";
      ASSERT_TRUE(same3(a.dir, b.dir)) << "dir";
      ASSERT_TRUE(same3(a.albedo, b.albedo)) << "albedo";
      ASSERT_EQ(bitsOf(a.eps), bitsOf(b.eps));
      ASSERT_EQ(bitsOf(a.t), bitsOf(b.t));
      ASSERT_EQ(bitsOf(a.hitU), bitsOf(b.hitU));
      ASSERT_EQ(bitsOf(a.hitV), bitsOf(b.hitV));
      ASSERT_EQ(bitsOf(a.time), bitsOf(b.time));
      ASSERT_EQ(a.geomID, b.geomID);
      ASSERT_EQ(a.primID, b.primID);
      ASSERT_EQ(a.instID, b.instID);
      ASSERT_EQ(a.object, b.object);
    }
  }
}

// Closest hits of rays between points of the scene's bounds (enlarged),
// from the sampler's points: a spread of primitives, instances and angles.
std::vector<RayHit> tracedHits(const Scene& scene, size_t want) {
  const Bounds3& b = scene.bounds();
  const Vec3 lo = b.lo - b.diagonal() * 0.25f, size = b.diagonal() * 1.5f;
  const uint32_t key = Sampler(3).pixelKey(1, 2);
  std::vector<RayHit> hits;
  for (uint32_t i = 0; hits.size() < want && i < 64 * want; ++i) {
    const Sample2 a = Sampler::get2D(key, i, kFirstIntegratorDim), c = Sampler::get2D(key, i, kFirstIntegratorDim + 2);
    const Sample2 d = Sampler::get2D(key, i, kFirstIntegratorDim + 4);
    const Vec3 from = lo + size * Vec3(a.u, a.v, c.u);
    const Vec3 to = b.lo + b.diagonal() * Vec3(c.v, d.u, d.v);
    const RayHit h = traceClosest(scene, from, (to - from) * (0.5f + 4.0f * d.u));
    if (h.hit.geomID != RTC_INVALID_GEOMETRY_ID) hits.push_back(h);
  }
  return hits;
}

TEST(FastPaths, SurfaceHitLanesEqualTheScalarForm) {
  const std::string dir = tempDir("fast_paths_surface_lanes");
  GltfBuilder g;
  // A bent quad with normals of different lengths, one of them zero.
  const int bent = g.push(
      "meshes",
      {{"primitives",
        json::array({{{"attributes",
                       {{"POSITION", g.positions({{-1, -1, 0}, {1, -1, 0.3f}, {1, 1, 0}, {-1, 1, -0.4f}})},
                        {"NORMAL", g.vec3({{0, 0, 1}, {0.3f, 0, 2}, {0, 0, 0}, {-0.2f, 0.1f, 0.5f}})}}},
                      {"indices", g.indices(std::vector<uint16_t>{0, 1, 2, 0, 2, 3})}}})}});
  const int plain = g.quadMesh(2.0f);  // no normals
  g.node({{"mesh", bent}});
  g.node({{"mesh", bent}, {"translation", {0, 0, 2}}, {"scale", {-1, 1.5, 1}}});  // mirrored instance
  g.node({{"mesh", bent}, {"translation", {3, 0, 1}}, {"rotation", {0, 0.3826834, 0, 0.9238795}}});
  g.node({{"mesh", plain}, {"translation", {0, 0, -3}}});
  g.scene({0, 1, 2, 3});
  auto scene = loadGltf(g.writeGltf(dir, "lanes"));
  ASSERT_EQ(scene->instances().size(), 3u);
  const std::vector<RayHit> hits = tracedHits(*scene, 400);
  for (bool albedo : {false, true}) expectSameHits(*scene, hits, albedo);

  const std::string viking = sharedScene("viking_room/viking_room.glb");
  OBSCURA_NEED_SHARED_SCENE(viking);
  auto room = loadGltf(viking);
  expectSameHits(*room, tracedHits(*room, 2000), true);
}


// The bilinear repeat lookup at (u, v) written from its definition (floor in
// double, the remainder modulo the size, the same float expression as
// Texture::sample), over texels at(x, y) of a w x h image.
template <class At>
Vec3 referenceBilinear(float u, float v, int w, int h, const At& at) {
  const double x = double(u) * w - 0.5, y = double(v) * h - 0.5;
  const double fx = std::floor(x), fy = std::floor(y);
  const float tx = float(x - fx), ty = float(y - fy);
  const int x0 = ((int(fx) % w) + w) % w, x1 = (x0 + 1) % w;
  const int y0 = ((int(fy) % h) + h) % h, y1 = (y0 + 1) % h;
  const Vec3 a = at(x0, y0) * (1 - tx) + at(x1, y0) * tx;
  const Vec3 b = at(x0, y1) * (1 - tx) + at(x1, y1) * tx;
  return a * (1 - ty) + b * ty;
}

// Checks tex.sample against referenceBilinear, bit for bit, at the unit
// square's edges (u or v = 0, 2^-24, 1 - 2^-24), on a grid through the
// texel centres and edges, and on 4096 sampler points of pixel `key`.
template <class At>
void expectLookupsMatch(const Texture& tex, int w, int h, const At& at, uint32_t key, const std::string& what) {
  const auto check = [&](float u, float v) {
    const Vec3 got = tex.sample(u, v, WrapMode::Repeat, WrapMode::Repeat), want = referenceBilinear(u, v, w, h, at);
    for (int k = 0; k < 3; ++k)
      ASSERT_EQ(bitsOf(got[k]), bitsOf(want[k])) << what << " channel " << k << " at " << u << ", " << v;
  };
  std::vector<float> coords = {0.0f, 1.0f - 0x1p-24f, 0x1p-24f, 0.5f};
  for (int i = 0; i <= 2 * std::max(w, h); ++i) coords.push_back(float(i) / float(2 * std::max(w, h)) * 0.999999f);
  for (float u : coords)
    for (float v : coords) check(u, v);
  for (uint32_t i = 0; i < 4096; ++i) {
    const Sample2 s = Sampler::get2D(key, i, kFirstIntegratorDim);
    check(s.u, s.v);
  }
}

// Texture::sample's repeat lookup inside the unit square (the albedo AOV's
// common case, which skips footprint()'s range cases) equals a bilinear
// lookup written here from its definition: floor in double, the remainder
// modulo the size, the texels from the file's 16-bit values, and the same
// float expression. At the square's edges (u or v = 0, 2^-24, 1 - 2^-24), on
// a grid through the texel centres and edges, and on sampler points, for a
// power-of-two and an odd size.
TEST(FastPaths, TextureUnitSquareLookups) {
  const std::string dir = tempDir("fast_paths_texture");
  for (auto [w, h] : {std::pair{8, 4}, std::pair{5, 3}}) {
    const std::string path = writeRgbTexture(dir + "/t" + std::to_string(w) + ".png", w, h, [](double u, double v) {
      return Vec3(float(u), float(v * v), float(0.3 + 0.5 * u * v));
    });
    const Texture tex(readBytes(path), path, false);
    tex.decode();
    ASSERT_EQ(tex.width(), w);
    // The texels as decode() forms them from the 16-bit file's values
    // (writeRgbTexture: row 0 at the top, v = 1 - (y + 0.5) / h).
    std::vector<Vec3> T(size_t(w) * size_t(h));
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double cu = (x + 0.5) / w, cv = 1.0 - (y + 0.5) / h;
        const Vec3 c(float(cu), float(cv * cv), float(0.3 + 0.5 * cu * cv));
        Vec3& t = T[size_t(y) * size_t(w) + size_t(x)];
        for (int k = 0; k < 3; ++k) t[k] = float(std::lround(std::clamp(c[k], 0.0f, 1.0f) * 65535)) / 65535.0f;
      }
    const auto at = [&](int i, int j) { return T[size_t(j) * size_t(w) + size_t(i)]; };
    expectLookupsMatch(tex, w, h, at, Sampler(5).pixelKey(2, 2), std::to_string(w) + "x" + std::to_string(h));
  }
}

// The same for 8-bit images (the kind glTF scenes ship, the viking room's
// among them), whose texels decode() keeps as bytes and reads through its
// 256-entry transfer table (the test above covers 16-bit files only): sRGB and linear, RGB and RGBA (alpha must not
// leak into the colour), against the reference bilinear lookup over the
// file's bytes through the transfer function.
TEST(FastPaths, Texture8BitUnitSquareLookups) {
  const std::string dir = tempDir("fast_paths_texture8");
  for (auto [w, h] : {std::pair{8, 4}, std::pair{5, 3}, std::pair{64, 33}})
    for (int channels : {3, 4})
      for (bool srgb : {false, true}) {
        // Bytes that hit every value of the table and differ per channel.
        std::vector<uint8_t> px(size_t(w) * size_t(h) * size_t(channels));
        for (size_t i = 0; i < px.size(); ++i) px[i] = uint8_t((i * 37 + i / 7) & 0xff);
        const std::string path = dir + "/t" + std::to_string(w) + "_" + std::to_string(channels) + ".png";
        {
          auto out = OIIO::ImageOutput::create(path);
          OIIO::ImageSpec spec(w, h, channels, OIIO::TypeDesc::UINT8);
          spec.attribute("oiio:UnassociatedAlpha", 1);  // the bytes as given: no un-premultiplying
          ASSERT_TRUE(out && out->open(path, spec)) << path;
          ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data())) << path;
          out->close();
        }
        const Texture tex(readBytes(path), path, srgb);
        tex.decode();
        ASSERT_EQ(tex.width(), w);
        ASSERT_EQ(tex.height(), h);
        const auto decoded = [&](uint8_t b) { return srgb ? srgbToLinear(float(b) / 255.0f) : float(b) / 255.0f; };
        const auto at = [&](int x, int y) {
          const uint8_t* p = &px[(size_t(y) * size_t(w) + size_t(x)) * size_t(channels)];
          return Vec3(decoded(p[0]), decoded(p[1]), decoded(p[2]));
        };
        expectLookupsMatch(tex, w, h, at, Sampler(9).pixelKey(1, 3),
                           std::to_string(w) + "x" + std::to_string(h) + "x" + std::to_string(channels) +
                               (srgb ? " srgb" : ""));
      }
}

}  // namespace
}  // namespace obscura::test
