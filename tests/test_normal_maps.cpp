// glTF normalTexture (issue #37): tangents, the bent shading normal and its
// effect on AO against closed forms (docs/math.md §16), --normal-maps off,
// and KHR_texture_transform on every texture the renderer reads.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "core/scene/scene.h"
#include "core/scene/surface.h"
#include "core/scene/tangents.h"
#include "core/image/texture.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr double kPi = 3.14159265358979323846;

// --- tangent generation ------------------------------------------------------

// A quad in the z = 0 plane whose uvs are an affine image of its positions,
// (u, v_up) = A (x, y) + o with v_up = 1 - v_file (glTF's v runs down): the
// analytic tangent is dP/du, the first column of A^-1, and the bitangent
// dP/dv_up the second; w = +1 when cross(N, T) points along dP/dv_up.
TEST(NormalMaps, GeneratedTangentsMatchTheAnalyticTangentOfAUvMappedQuad) {
  const std::vector<Vec3> pos = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  const std::vector<uint32_t> idx = {0, 1, 2, 0, 2, 3};
  struct Case {
    const char* name;
    double a00, a01, a10, a11;  // A
  };
  const Case cases[] = {{"identity", 1, 0, 0, 1},
                        {"rotated 30 degrees, scaled 2", 2 * std::cos(0.5236), -2 * std::sin(0.5236), 2 * std::sin(0.5236),
                         2 * std::cos(0.5236)},
                        {"sheared", 1, 0.5, 0, 1},
                        {"mirrored in u", -1, 0, 0, 1}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::vector<float> uvs;
    for (const Vec3& p : pos) {
      const double u = c.a00 * p.x + c.a01 * p.y + 0.25, vUp = c.a10 * p.x + c.a11 * p.y + 0.5;
      uvs.push_back(float(u)), uvs.push_back(float(1.0 - vUp));
    }
    // A^-1's columns: dP/du and dP/dv_up in (x, y).
    const double det = c.a00 * c.a11 - c.a01 * c.a10;
    const double tu[2] = {c.a11 / det, -c.a10 / det}, tv[2] = {-c.a01 / det, c.a00 / det};
    const double tl = std::hypot(tu[0], tu[1]);
    // w: the sign of cross(N, T) . dP/dv_up with N = +z: cross(z, T) = (-Ty, Tx).
    const double w = (-tu[1] * tv[0] + tu[0] * tv[1]) < 0 ? -1 : 1;
    for (bool withNormals : {false, true}) {
      const std::vector<Vec3> normals = withNormals ? std::vector<Vec3>(4, Vec3(0, 0, 1)) : std::vector<Vec3>{};
      const std::vector<float> t = generateTangents(pos, normals, uvs, idx, true);
      ASSERT_EQ(t.size(), 16u);
      for (int v = 0; v < 4; ++v) {
        // The uvs are rounded to float; the generator works in double: the
        // tangent agrees to a few float ulps.
        EXPECT_NEAR(t[4 * v], tu[0] / tl, 1e-6) << v;
        EXPECT_NEAR(t[4 * v + 1], tu[1] / tl, 1e-6) << v;
        EXPECT_NEAR(t[4 * v + 2], 0.0, 1e-6) << v;
        EXPECT_EQ(t[4 * v + 3], float(w)) << v;
      }
    }
  }
}

// --- scenes --------------------------------------------------------------------

// A 64x64 plane (the builder's quad, half-size 50: T = +x, B = +y, N = +z) seen
// from (0, 0, 1) looking down -z, yfov 0.5 rad, its material's normal map a
// constant 4x4 16-bit PNG of `texel` (linear) with `scale`; `extra` is
// merged into normalTexture (an extension). `mapped` false: no normalTexture.
std::string tiltedPlane(const std::string& dir, const std::string& name, Vec3 texel, double scale, bool mapped,
                        const json& extra = json::object()) {
  writeRgbTexture(dir + "/" + name + ".png", 4, 4, [&](double, double) { return texel; });
  GltfBuilder g;
  json mat = {{"name", "tilted"}};
  if (mapped) {
    g.push("images", {{"uri", name + ".png"}});
    g.push("textures", {{"source", 0}});
    json nt = {{"index", 0}, {"scale", scale}};
    nt.update(extra);
    mat["normalTexture"] = nt;
  }
  const int m = g.push("materials", mat);
  g.push("cameras", perspective("front", 0.5, 0.01));
  const int quad = g.quadMesh(50.0f, m, true);
  g.node({{"mesh", quad}});
  g.node({{"camera", 0}, {"translation", {0, 0, 1}}});
  g.scene({0, 1});
  return g.writeGltf(dir, name);
}

// The texel as the renderer decodes it (16-bit, linear).
Vec3 decodedTexel(const std::string& png) {
  Texture t(readBytes(png), png, false);
  t.decode();
  return t.sample(0.5f, 0.5f, WrapMode::Repeat, WrapMode::Repeat);
}

// The map's normal in the plane's frame (T = +x, B = +y, N = +z), in double.
std::array<double, 3> mappedNormal(Vec3 c, double scale) {
  const double x = (2.0 * c.x - 1.0) * scale, y = (2.0 * c.y - 1.0) * scale, z = 2.0 * c.z - 1.0;
  const double l = std::sqrt(x * x + y * y + z * z);
  return {x / l, y / l, z / l};
}

RenderSettings aovSettings(int w, int spp) {
  RenderSettings s;
  s.width = s.height = w;
  s.spp = spp;
  s.aovs = true;
  return s;
}

double meanOf(const Film& f, int c) {
  double sum = 0;
  for (int y = 0; y < f.height(); ++y)
    for (int x = 0; x < f.width(); ++x) sum += f.at(c, x, y);
  return sum / (double(f.width()) * f.height());
}

// --- the bent normal and AO ------------------------------------------------------

// A constant map tilting the normal by alpha on an open plane: every hit's
// shading normal is the map's (the N AOV, to float rounding), and AO, the
// cosine-weighted fraction of directions about it that are above the
// geometric plane (docs/math.md §1: below it the surface itself occludes),
// is (1 + cos alpha) / 2 (docs/math.md §16.5).
TEST(NormalMaps, ConstantTiltedMapOnAnOpenPlaneGivesTheClosedFormAo) {
  const std::string dir = tempDir("normal_maps_tilt");
  // 30 degrees towards +x and -y in the map (x, y) plane, then scale 0.7.
  const double tilt = 30.0 * kPi / 180.0, azimuth = -0.4, scale = 0.7;
  const Vec3 texel(float(0.5 + 0.5 * std::sin(tilt) * std::cos(azimuth) / scale),
                   float(0.5 + 0.5 * std::sin(tilt) * std::sin(azimuth) / scale), float(0.5 + 0.5 * std::cos(tilt)));
  const std::string path = tiltedPlane(dir, "tilt", texel, scale, true);
  const auto n = mappedNormal(decodedTexel(dir + "/tilt.png"), scale);
  const double cosAlpha = n[2];
  ASSERT_NEAR(cosAlpha, std::cos(tilt), 1e-3);  // the 16-bit quantization of the texel

  auto scene = loadGltf(path);
  ASSERT_TRUE(scene->hasNormalMaps());
  const int w = 32, spp = 64, rays = 4;
  const Film f = renderWith(*scene, scene->cameras[0], "ao", {"rays=" + std::to_string(rays)}, aovSettings(w, spp));
  // The N AOV: the mapped normal at every pixel (float rounding of the frame
  // and the normalization: a few ulps of 1).
  for (int y = 0; y < w; ++y)
    for (int x = 0; x < w; ++x) {
      ASSERT_NEAR(f.at(kNX, x, y), n[0], 4e-6) << x << "," << y;
      ASSERT_NEAR(f.at(kNY, x, y), n[1], 4e-6) << x << "," << y;
      ASSERT_NEAR(f.at(kNZ, x, y), n[2], 4e-6) << x << "," << y;
    }
  // AO: each ray a Bernoulli draw of p = (1 + cos alpha) / 2; the image mean
  // over w^2 spp rays of them has a standard error of at most
  // bernoulliStdErr (the stratified samples only lower it).
  const double p = 0.5 * (1.0 + cosAlpha);
  const double se = bernoulliStdErr(p, double(w) * w * spp * rays);
  EXPECT_NEAR(meanOf(f, kR), p, 4 * se) << "SE " << se;
  // Without the map, alpha = 0: 1 but for the rare direction that rounds
  // into the plane (a sample on the disk's rim), which docs/math.md §1
  // counts as blocked - one or two of these 262144 rays.
  const Film off = renderWith(*loadGltf(tiltedPlane(dir, "flat", texel, scale, false)), scene->cameras[0], "ao",
                              {"rays=" + std::to_string(rays)}, aovSettings(w, spp));
  EXPECT_NEAR(meanOf(off, kR), 1.0, 8.0 / (double(w) * w * spp * rays));
}

// A flat texel ((0.5, 0.5, 1) after scale 0, or any texel at scale 0) is
// the interpolated normal: the render equals the unmapped one bit for bit.
// The 8-bit "flat" texel (128, 128, 255) decodes to x = y = 1/255, a tilt
// of atan(sqrt(2)/255) (0.32 degrees) as glTF's 2c - 1 prescribes: its N AOV
// is that tilt to float rounding.
TEST(NormalMaps, AFlatMapRendersAsNoMap) {
  const std::string dir = tempDir("normal_maps_flat");
  const Camera cam = makeLookAtCamera({0, 0, 1}, {0, 0, 0}, {0, 1, 0}, 0.5f, "front");
  const RenderSettings s = aovSettings(16, 8);
  const Film none = renderWith(*loadGltf(tiltedPlane(dir, "none", Vec3(0.5f, 0.5f, 1), 1.0, false)), cam, "ao",
                               {"rays=2"}, s);
  const Film zero = renderWith(*loadGltf(tiltedPlane(dir, "zero", Vec3(0.9f, 0.2f, 0.8f), 0.0, true)), cam, "ao",
                               {"rays=2"}, s);
  expectSameFilm(zero, none, "scale 0 against no map");

  // (128, 128, 255) as an 8-bit PNG.
  GltfBuilder g;
  const std::string png = dir + "/flat8.png";
  {
    // An 8-bit RGB PNG of the flat texel.
    std::vector<unsigned char> rgb;
    for (int i = 0; i < 4; ++i) rgb.insert(rgb.end(), {128, 128, 255});
    auto out = OIIO::ImageOutput::create(png);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(2, 2, 3, OIIO::TypeDesc::UINT8);
    ASSERT_TRUE(out->open(png, spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, rgb.data()));
    out->close();
  }
  g.push("images", {{"uri", "flat8.png"}});
  g.push("textures", {{"source", 0}});
  const int m = g.push("materials", {{"normalTexture", {{"index", 0}}}});
  g.node({{"mesh", g.quadMesh(50.0f, m, true)}});
  g.scene({0});
  const Film eight = renderWith(*loadGltf(g.writeGltf(dir, "flat8")), cam, "ao", {"rays=2"}, s);
  const double d = 1.0 / 255.0, l = std::sqrt(2 * d * d + 1);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      ASSERT_NEAR(eight.at(kNX, x, y), d / l, 4e-6);
      ASSERT_NEAR(eight.at(kNY, x, y), d / l, 4e-6);
      ASSERT_NEAR(eight.at(kNZ, x, y), 1 / l, 4e-6);
    }
}

// A mirroring node transform (scale -1 in x) mirrors the map's bumps with the
// surface: the bent normal of the mirrored copy is (-nx, ny, nz) of the
// plain one's (nx, ny, nz) - for a mesh baked into world space (the
// loader flips TANGENT.w) and for an instanced one (the hit flips it),
// whose frames docs/math.md §16.1 derives.
TEST(NormalMaps, MirroredCopiesMirrorTheBentNormal) {
  const std::string dir = tempDir("normal_maps_mirror");
  const Vec3 texel(0.7f, 0.4f, 0.9f);
  writeRgbTexture(dir + "/m.png", 4, 4, [&](double, double) { return texel; });
  const auto n = mappedNormal(decodedTexel(dir + "/m.png"), 1.0);
  for (bool instanced : {false, true}) {
    SCOPED_TRACE(instanced ? "instanced" : "baked");
    GltfBuilder g;
    g.push("images", {{"uri", "m.png"}});
    g.push("textures", {{"source", 0}});
    const int m = g.push("materials", {{"normalTexture", {{"index", 0}}}});
    const int a = g.quadMesh(1.0f, m, true);
    const int b = instanced ? a : g.quadMesh(1.0f, m, true);
    g.node({{"mesh", a}, {"translation", {1.5, 0, 0}}});
    g.node({{"mesh", b}, {"translation", {-1.5, 0, 0}}, {"scale", {-1, 1, 1}}});
    g.scene({0, 1});
    auto scene = loadGltf(g.writeGltf(dir, instanced ? "instanced" : "baked"));
    EXPECT_EQ(scene->instances().size(), instanced ? 2u : 0u);
    const Camera cam = makeLookAtCamera({0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 0.58f, "top");
    RenderSettings s = aovSettings(32, 2);
    s.width = 64;
    const Film f = renderWith(*scene, cam, "ao", {}, s);
    size_t left = 0, right = 0;
    for (int y = 10; y < 22; ++y)
      for (int x = 0; x < 64; ++x) {
        if (f.at(kA, x, y) < 1) continue;
        const bool mirrored = x < 32;
        (mirrored ? left : right)++;
        ASSERT_NEAR(f.at(kNX, x, y), mirrored ? -n[0] : n[0], 4e-6) << x << "," << y;
        ASSERT_NEAR(f.at(kNY, x, y), n[1], 4e-6) << x << "," << y;
        ASSERT_NEAR(f.at(kNZ, x, y), n[2], 4e-6) << x << "," << y;
      }
    EXPECT_GT(left, 50u);
    EXPECT_GT(right, 50u);
  }
}

// --normal-maps off (LoadOptions::normalMaps = false) loads the file as if
// it had no normalTexture: no tangents, nothing decoded, the same bits.
TEST(NormalMaps, OffRendersAsTheUnmappedFile) {
  const std::string dir = tempDir("normal_maps_off");
  const Vec3 texel(0.8f, 0.3f, 0.7f);
  LoadOptions off;
  off.normalMaps = false;
  auto mappedOff = loadGltf(tiltedPlane(dir, "mapped", texel, 1.0, true), off);
  EXPECT_FALSE(mappedOff->hasNormalMaps());
  EXPECT_EQ(mappedOff->materials[0].normalTexture, -1);
  EXPECT_FALSE(mappedOff->dataTextures[0]->decoded());
  auto unmapped = loadGltf(tiltedPlane(dir, "unmapped", texel, 1.0, false));
  const RenderSettings s = aovSettings(16, 8);
  const Film a = renderWith(*mappedOff, mappedOff->cameras[0], "ao", {"rays=2"}, s);
  const Film b = renderWith(*unmapped, unmapped->cameras[0], "ao", {"rays=2"}, s);
  EXPECT_FALSE(mappedOff->dataTextures[0]->decoded()) << "a render with normal maps off decodes none";
  expectSameFilm(a, b, "--normal-maps off against the file without normalTexture");
  // And the CLI's flag reaches the load (and the header).
  const std::string exr = dir + "/off.exr";
  const CliResult r = runCli({"render", dir + "/mapped.gltf", "-o", exr, "--res", "16x16", "--spp", "8", "-p", "rays=2",
                              "--normal-maps", "off"},
                             dir + "/off.err");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack rb = readExr(exr);
  ASSERT_TRUE(rb.ok);
  EXPECT_EQ(rb.spec.get_string_attribute("obscura:normalMaps"), "off");
  const CliResult bad = runCli({"render", dir + "/mapped.gltf", "-o", dir + "/bad.exr", "--normal-maps", "maybe"},
                               dir + "/bad.err");
  EXPECT_EQ(bad.exitCode, 1);
  EXPECT_NE(bad.stderrText.find("--normal-maps: expected on or off, got 'maybe'"), std::string::npos) << bad.stderrText;
}

// The SSE hit stage (computeSurfaceHits) gives normal-mapped hits the scalar
// form's bits, and the bent normal keeps the view's mirror direction above
// the geometric surface (docs/math.md §16.4) even when the map tilts by 80
// degrees and the view grazes.
TEST(NormalMaps, BentNormalsMatchTheScalarFormAndKeepReflectionsAbove) {
  const std::string dir = tempDir("normal_maps_hits");
  const double tilt = 80.0 * kPi / 180.0;
  auto scene = loadGltf(tiltedPlane(dir, "steep", Vec3(float(0.5 + 0.5 * std::sin(tilt)), 0.5f, float(0.5 + 0.5 * std::cos(tilt))),
                                    1.0, true));
  scene->decodeNormalMaps();
  std::vector<RayHit> rays;
  for (int i = 0; i < 64; ++i) {
    // From every side, down to 5 degrees above the plane.
    const double az = 2 * kPi * i / 64.0, el = (5.0 + 80.0 * (i % 8) / 7.0) * kPi / 180.0;
    const Vec3 eye(float(3 * std::cos(el) * std::cos(az)), float(3 * std::cos(el) * std::sin(az)), float(3 * std::sin(el)));
    const RayHit rh = traceClosest(*scene, eye, Vec3(0.3f, -0.7f, 0) - eye);
    ASSERT_NE(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID);
    rays.push_back(rh);
  }
  std::vector<uint32_t> lanes(rays.size());
  for (size_t i = 0; i < lanes.size(); ++i) lanes[i] = uint32_t(i);
  std::vector<SurfaceHit> fast(rays.size());
  computeSurfaceHits(*scene, rays.data(), lanes.data(), rays.size(), false, fast.data());
  size_t lifted = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    SurfaceHit slow;
    computeSurfaceHit(*scene, rays[i], false, slow);
    const SurfaceHit& h = fast[i];
    ASSERT_EQ(std::memcmp(&h.ns, &slow.ns, sizeof(Vec3)), 0) << i;
    ASSERT_EQ(std::memcmp(&h.ng, &slow.ng, sizeof(Vec3)), 0) << i;
    const Vec3 I = -h.dir;
    const Vec3 R = h.ns * (2.0f * dot(h.ns, I)) - I;
    const float q = std::min(0.9f * dot(h.ng, I), 0.01f);
    // The lifted reflection sits at elevation q, to float rounding.
    EXPECT_GE(dot(R, h.ng), q - 1e-5f) << i;
    EXPECT_NEAR(length(h.ns), 1.0f, 1e-6f);
    if (std::abs(dot(R, h.ng) - q) < 1e-5f) ++lifted;
  }
  EXPECT_GT(lifted, 0u) << "the steep map at grazing views needs the lift";
}

// --- KHR_texture_transform ------------------------------------------------------

// The transform's (s, t) = T R S (u, v) in double, as the extension defines it.
std::array<double, 2> khr(double u, double v, const double off[2], double rot, const double sc[2]) {
  const double c = std::cos(rot), s = std::sin(rot);
  return {c * sc[0] * u + s * sc[1] * v + off[0], -s * sc[0] * u + c * sc[1] * v + off[1]};
}

// The KHR_texture_transform extension object of (off, rot, sc).
json khrJson(const double off[2], double rot, const double sc[2]) {
  return {{"KHR_texture_transform", {{"offset", {off[0], off[1]}}, {"rotation", rot}, {"scale", {sc[0], sc[1]}}}}};
}

// A mesh of one quad [-1, 1]^2 (z = 0) with `material`, its uvs the
// builder quad's, or (baked) their image under the transform; the scene
// of one node using it.
void transformQuad(GltfBuilder& g, int material, bool baked, const double off[2], double rot, const double sc[2]) {
  const double uv[4][2] = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
  std::vector<std::array<float, 2>> uvs;
  for (const auto& t : uv) {
    const auto st = baked ? khr(t[0], t[1], off, rot, sc) : std::array<double, 2>{t[0], t[1]};
    uvs.push_back({float(st[0]), float(st[1])});
  }
  json prim = {{"attributes",
                {{"POSITION", g.positions({{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}})}, {"TEXCOORD_0", g.vec2(uvs)}}},
               {"indices", g.indices(std::vector<uint16_t>{0, 1, 2, 0, 2, 3})},
               {"material", material}};
  g.node({{"mesh", g.push("meshes", {{"primitives", json::array({prim})}})}});
  g.scene({0});
}

// A MASK cut-out (and an albedo) read through KHR_texture_transform equals
// the same material with the transform baked into the quad's uvs: the same
// coverage, and albedo to the rounding of the uv (the texture's slope, at
// most 1 per texel over 16 texels, times a few float ulps of the uv).
TEST(TextureTransform, TransformedCutoutEqualsTheTransformBakedIntoTheUvs) {
  const std::string dir = tempDir("texture_transform");
  // Alpha: a 16x16 checker of 4-texel squares; colour white (the albedo
  // test below reads a second, smooth texture).
  writeAlphaTexture(dir + "/mask.png", 16, 16, [](int x, int y) { return ((x / 4 + y / 4) % 2) ? 1.0 : 0.0; });
  const double off[2] = {0.3, -0.2}, rot = 0.7, sc[2] = {1.5, 0.75};
  const auto build = [&](bool baked) {
    GltfBuilder g;
    g.push("images", {{"uri", "mask.png"}});
    g.push("textures", {{"source", 0}});
    json info = {{"index", 0}};
    if (!baked) info["extensions"] = khrJson(off, rot, sc);
    const int m = g.push("materials", {{"alphaMode", "MASK"}, {"pbrMetallicRoughness", {{"baseColorTexture", info}}}});
    transformQuad(g, m, baked, off, rot, sc);
    return g.writeGltf(dir, baked ? "baked" : "transformed");
  };
  WarningCapture warnings;
  auto transformed = loadGltf(build(false));
  auto baked = loadGltf(build(true));
  EXPECT_EQ(warnings.count("KHR_texture_transform"), 0u) << warnings.all();
  EXPECT_FALSE(transformed->materials[0].transform.identity);
  const Camera cam = makeLookAtCamera({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 0.8f, "front");
  const RenderSettings s = aovSettings(48, 4);
  const Film a = renderWith(*transformed, cam, "ao", {}, s);
  const Film b = renderWith(*baked, cam, "ao", {}, s);
  // The checker's edges are 4 texels apart and alpha crosses the cutoff
  // over one texel: a sample flips only within a few float ulps of an edge
  // (probability ~1e-6 per sample, ~1e-2 over the image), so the coverage
  // planes are equal.
  size_t covered = 0;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 48; ++x) {
      ASSERT_EQ(a.at(kA, x, y), b.at(kA, x, y)) << x << "," << y;
      covered += a.at(kA, x, y) > 0;
    }
  // Both some holes and some surface.
  EXPECT_GT(covered, 48u * 48u / 8);
  EXPECT_LT(covered, 48u * 48u * 7 / 8);
}

// Albedo (baseColorTexture) and roughness (metallicRoughnessTexture) read
// through their transforms equal the transforms baked into the uvs, hit by
// hit. Both textures are smooth and periodic (16 texels of
// 0.5 + 0.4 sin 2 pi u ...): bilinear slopes of at most 0.4 * 2 pi = 2.5 per
// uv unit (times at most 2.4 for the sRGB decoding of albedo), and the two
// uvs differ by a few float ulps of values below 4 (~2e-6): 1.2e-5 at most.
TEST(TextureTransform, AlbedoAndRoughnessReadTheTransformedUvs) {
  const std::string dir = tempDir("texture_transform_albedo");
  const auto wave = [](double u, double v) {
    return Vec3(float(0.5 + 0.4 * std::sin(2 * kPi * u)), float(0.5 + 0.4 * std::cos(2 * kPi * v)),
                float(0.5 + 0.4 * std::sin(2 * kPi * (u + v))));
  };
  writeRgbTexture(dir + "/wave.png", 16, 16, wave);
  const double off[2] = {-0.35, 0.6}, rot = -1.1, sc[2] = {0.8, 2.5};
  const json ext = khrJson(off, rot, sc);
  const auto build = [&](bool baked) {
    GltfBuilder g;
    g.push("images", {{"uri", "wave.png"}});
    g.push("textures", {{"source", 0}});
    json base = {{"index", 0}}, rough = {{"index", 0}};
    if (!baked) base["extensions"] = ext, rough["extensions"] = ext;
    const int m = g.push("materials", {{"pbrMetallicRoughness", {{"baseColorTexture", base}, {"metallicRoughnessTexture", rough}}}});
    transformQuad(g, m, baked, off, rot, sc);
    return loadGltf(g.writeGltf(dir, baked ? "baked" : "transformed"));
  };
  auto a = build(false), b = build(true);
  a->textures[0]->decode(), b->textures[0]->decode();
  double spread = 0;
  for (int j = 0; j < 24; ++j)
    for (int i = 0; i < 24; ++i) {
      const Vec3 target(float(-0.95 + 1.9 * (i + 0.5) / 24), float(-0.95 + 1.9 * (j + 0.5) / 24), 0);
      const Vec3 eye = target + Vec3(0.1f, 0.2f, 2.0f);
      SurfaceHit ha, hb;
      computeSurfaceHit(*a, traceClosest(*a, eye, target - eye), true, ha);
      computeSurfaceHit(*b, traceClosest(*b, eye, target - eye), true, hb);
      EXPECT_NEAR(ha.albedo.x, hb.albedo.x, 1.2e-5) << i << "," << j;
      EXPECT_NEAR(ha.albedo.y, hb.albedo.y, 1.2e-5) << i << "," << j;
      EXPECT_NEAR(ha.albedo.z, hb.albedo.z, 1.2e-5) << i << "," << j;
      EXPECT_NEAR(surfaceRoughness(*a, ha), surfaceRoughness(*b, hb), 1.2e-5) << i << "," << j;
      spread = std::max(spread, double(std::abs(ha.albedo.x - a->materials[0].baseColorFactor.x)));
    }
  EXPECT_GT(spread, 0.1) << "the texture varies over the quad";
}

TEST(TextureTransform, BadTransformsAreRefusedAndOtherTexCoordsWarned) {
  const std::string dir = tempDir("texture_transform_bad");
  writeAlphaTexture(dir + "/t.png", 2, 2, [](int, int) { return 1.0; });
  const auto file = [&](const std::string& name, const json& ext, bool normal) {
    GltfBuilder g;
    g.push("images", {{"uri", "t.png"}});
    g.push("textures", {{"source", 0}});
    json info = {{"index", 0}, {"extensions", {{"KHR_texture_transform", ext}}}};
    const int m = normal ? g.push("materials", {{"normalTexture", info}})
                         : g.push("materials", {{"pbrMetallicRoughness", {{"baseColorTexture", info}}}});
    g.node({{"mesh", g.quadMesh(1.0f, m, true)}});
    g.scene({0});
    return g.writeGltf(dir, name);
  };
  const auto refused = [&](const std::string& path, const std::string& needle) {
    try {
      loadGltf(path);
      ADD_FAILURE() << "accepted " << path;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  refused(file("three", {{"offset", {0, 0, 0}}}, false),
          "materials[0].pbrMetallicRoughness.baseColorTexture.extensions.KHR_texture_transform.offset: expected 2 numbers");
  refused(file("text", {{"rotation", "half"}}, true), "materials[0].normalTexture.extensions.KHR_texture_transform.rotation");
  WarningCapture warnings;
  auto other = loadGltf(file("tc1", {{"texCoord", 1}}, false));
  EXPECT_EQ(other->materials[0].texture, -1);
  EXPECT_EQ(warnings.count("TEXCOORD_1"), 1u) << warnings.all();
  // texCoord 0 in the extension overrides the textureInfo's 1.
  GltfBuilder g;
  g.push("images", {{"uri", "t.png"}});
  g.push("textures", {{"source", 0}});
  const int m = g.push("materials", {{"pbrMetallicRoughness",
                                      {{"baseColorTexture",
                                        {{"index", 0}, {"texCoord", 1}, {"extensions", {{"KHR_texture_transform", {{"texCoord", 0}}}}}}}}}});
  g.node({{"mesh", g.quadMesh(1.0f, m, true)}});
  g.scene({0});
  EXPECT_EQ(loadGltf(g.writeGltf(dir, "override"))->materials[0].texture, 0);
}

// The damaged helmet (the one shared scene with a normalTexture, no
// TANGENT): tangents are generated, every one unit and perpendicular to its
// vertex normal, and the map changes the shading normals.
TEST(NormalMaps, HelmetTangentsAreGeneratedAndBendItsNormals) {
  const std::string path = sharedScene("damaged_helmet/DamagedHelmet.gltf");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << missingSharedScene(path);
  auto on = loadGltf(path);
  ASSERT_TRUE(on->hasNormalMaps());
  LoadOptions o;
  o.normalMaps = false;
  auto off = loadGltf(path, o);
  ASSERT_FALSE(off->hasNormalMaps());
  const Camera cam = makeAutoCamera(on->bounds(), 1.0f);
  const RenderSettings s = aovSettings(48, 2);
  const Film a = renderWith(*on, cam, "ao", {}, s);
  const Film b = renderWith(*off, cam, "ao", {}, s);
  size_t covered = 0, bent = 0;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 48; ++x) {
      if (a.at(kA, x, y) < 1) continue;
      ++covered;
      const float d = a.at(kNX, x, y) * b.at(kNX, x, y) + a.at(kNY, x, y) * b.at(kNY, x, y) + a.at(kNZ, x, y) * b.at(kNZ, x, y);
      bent += d < 0.9999f;
    }
  ASSERT_GT(covered, 100u);
  EXPECT_GT(bent, covered / 10) << "the helmet's map bends its normals";
}

}  // namespace
}  // namespace obscura::test
