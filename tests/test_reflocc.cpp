// Reflection occlusion (integrators/reflocc.cpp, docs/math.md §12) against
// closed forms, and the material roughness it reads from glTF files.
//
// The scene of the mirror tests: a floor z = 0, a horizontal slab
// x in [-1, 1], y in [0.5, 3] at height H = 2, and a camera at E = (0, -6, 1),
// below the slab, looking down at the floor. A mirror ray from a floor
// point p continues the line from E' = (0, -6, -1), the camera's mirror
// image, through p: it meets the plane z = H at q = E' + k (p - E') with
// k = (H + Ez) / Ez = 3, an axis-aligned homothety, so the floor points
// whose mirror ray meets the slab form the rectangle
//   |p_x| <= 1/3,  p_y in [-6 + 6.5/3, -6 + 9/3] = [-3.8333, -3],
// and the ray's length to q is |q - p| = (k - 1) |p - E'|: within R when
// |p - E'| <= R / 2, a disc about (0, -6) on the floor of radius
// sqrt((R/2)^2 - 1). A pixel whose floor footprint (the quadrilateral of its
// corners' floor points, convex: a projective image of the pixel square)
// lies wholly inside that region must be exactly 0, one wholly outside
// exactly 1, whatever camera samples fell in it.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr double kSlabH = 2.0, kEyeZ = 1.0, kEyeY = -6.0;
constexpr double kK = (kSlabH + kEyeZ) / kEyeZ;  // the homothety's ratio, 3

struct MirrorScene {
  static constexpr int kW = 48, kH = 32;
  Scene scene;
  const Camera cam = makeLookAtCamera(Vec3(0, float(kEyeY), float(kEyeZ)), Vec3(0, -3, 0), Vec3(0, 0, 1), 0.5f, "mirror");
  const RasterCamera rc{cam, kW, kH};
  MirrorScene() {
    addPlane(scene, 50.0f);
    scene.addWorldPrimitive({{-1, 0.5f, 2}, {1, 0.5f, 2}, {1, 3, 2}, {-1, 3, 2}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
    scene.commit();
  }
  // The floor point seen through film position (fx, fy) of the kW x kH image.
  Vec3 floorAt(float fx, float fy) const {
    const Vec3 d = rc.direction(fx, fy);
    return rc.org + d * (-rc.org.z / d.z);
  }
};

// What every sample of pixel (x, y) must give at roughness 0 with distance
// R: 0 (all blocked), 1 (all open) or -1 (the footprint straddles the
// region's edge, within a margin of 10^-3 floor units - far above the ray
// offset, 50 * 2^-16 = 7.6e-4 along the ray, scaled by 1/(k-1) on the floor,
// and the 10^-7 a lobe of roughness 10^-4 spreads over these distances).
int mirrorExpectation(const MirrorScene& s, int x, int y, double R) {
  double bx0 = 1e30, bx1 = -1e30, by0 = 1e30, by1 = -1e30;
  for (int cy = 0; cy <= 1; ++cy)
    for (int cx = 0; cx <= 1; ++cx) {
      const Vec3 p = s.floorAt(float(x + cx), float(y + cy));
      bx0 = std::min(bx0, double(p.x)), bx1 = std::max(bx1, double(p.x));
      by0 = std::min(by0, double(p.y)), by1 = std::max(by1, double(p.y));
    }
  constexpr double m = 1e-3;
  const double rx0 = -1.0 / kK, rx1 = 1.0 / kK;
  const double ry0 = kEyeY + (0.5 - kEyeY) / kK, ry1 = kEyeY + (3.0 - kEyeY) / kK;
  const bool rectAll = bx0 > rx0 + m && bx1 < rx1 - m && by0 > ry0 + m && by1 < ry1 - m;
  const bool rectNone = bx1 < rx0 - m || bx0 > rx1 + m || by1 < ry0 - m || by0 > ry1 + m;
  // The disc |p - (0, kEyeY)| <= rho on the floor (everything when R = inf).
  bool discAll = true, discNone = false;
  if (std::isfinite(R)) {
    const double rho2 = (R / (kK - 1)) * (R / (kK - 1)) - kEyeZ * kEyeZ;
    const double rho = rho2 > 0 ? std::sqrt(rho2) : -1.0;
    const double fx = std::max(std::abs(bx0), std::abs(bx1)), fy = std::max(std::abs(by0 - kEyeY), std::abs(by1 - kEyeY));
    const double nx = (bx0 <= 0 && bx1 >= 0) ? 0 : std::min(std::abs(bx0), std::abs(bx1));
    const double ny = (by0 <= kEyeY && by1 >= kEyeY) ? 0 : std::min(std::abs(by0 - kEyeY), std::abs(by1 - kEyeY));
    discAll = std::hypot(fx, fy) < rho - m;
    discNone = std::hypot(nx, ny) > rho + m;
  }
  if (rectAll && discAll) return 0;
  if (rectNone || discNone) return 1;
  return -1;
}

// Roughness 0 (and lobes so narrow they stay within the margin) is the
// visibility of the mirror direction: pixel by pixel, 0 or 1 exactly.
TEST(ReflOcc, MirrorLobeIsTheVisibilityOfTheMirrorDirection) {
  const MirrorScene s;
  const double inf = std::numeric_limits<double>::infinity();
  for (const char* roughness : {"0", "1e-4", "1e-8"})
    for (double R : {inf, 5.5}) {
      SCOPED_TRACE(std::string("roughness ") + roughness + ", R " + std::to_string(R));
      const Film f = renderWith(s.scene, s.cam, "reflocc",
                                {std::string("roughness=") + roughness, "distance=" + formatFloat(R), "rays=2"},
                                passSettings(MirrorScene::kW, MirrorScene::kH, 8));
      int blocked = 0, open = 0, straddling = 0;
      for (int y = 0; y < MirrorScene::kH; ++y)
        for (int x = 0; x < MirrorScene::kW; ++x) {
          ASSERT_EQ(f.at(kA, x, y), 1.0f) << "every pixel sees the floor";
          const float v = f.at(kR, x, y);
          const int e = mirrorExpectation(s, x, y, R);
          if (e < 0) {
            ++straddling;
            EXPECT_TRUE(v >= 0.0f && v <= 1.0f) << x << "," << y << ": " << v;
            continue;
          }
          (e == 0 ? blocked : open) += 1;
          EXPECT_EQ(v, float(e)) << "pixel " << x << "," << y;
        }
      // The region is large on screen and the finite R cuts it: enough
      // decided pixels of both kinds for the check to mean something.
      EXPECT_GE(blocked, std::isfinite(R) ? 15 : 40);
      EXPECT_GE(open, 1000);
      EXPECT_LT(straddling, 150);
    }
}

// The covered mean at roughness 0 against the exact fraction of camera
// samples whose mirror ray is blocked. With the box filter a sample is
// uniform in its pixel; the fraction of a pixel's area whose floor point is
// in the (axis-aligned) region is integrated on a 64 x 64 midpoint grid of
// the film per pixel - an independent computation of the same expectation.
// Tolerance: per pixel spp x rays draws of a 0/1 indicator, at most
// Bernoulli variance; 4 standard errors of the mean over all pixels, plus
// the grid's error (at most one grid row and column of the straddling
// pixels: 2/64 of each, over the image).
TEST(ReflOcc, MirrorLobeMeanMatchesTheBlockedFraction) {
  const MirrorScene s;
  const int spp = 16;
  const Film f = renderWith(s.scene, s.cam, "reflocc", {"roughness=0"}, passSettings(MirrorScene::kW, MirrorScene::kH, spp));
  const double rx0 = -1.0 / kK, rx1 = 1.0 / kK;
  const double ry0 = kEyeY + (0.5 - kEyeY) / kK, ry1 = kEyeY + (3.0 - kEyeY) / kK;
  double expected = 0;
  int straddling = 0;
  constexpr int g = 64;
  for (int y = 0; y < MirrorScene::kH; ++y)
    for (int x = 0; x < MirrorScene::kW; ++x) {
      int in = 0;
      for (int j = 0; j < g; ++j)
        for (int i = 0; i < g; ++i) {
          const Vec3 p = s.floorAt(float(x + (i + 0.5) / g), float(y + (j + 0.5) / g));
          in += (p.x >= rx0 && p.x <= rx1 && p.y >= ry0 && p.y <= ry1) ? 1 : 0;
        }
      if (in > 0 && in < g * g) ++straddling;
      expected += 1.0 - double(in) / (g * g);
    }
  const double n = double(MirrorScene::kW * MirrorScene::kH);
  expected /= n;
  const double tol = 4 * bernoulliStdErr(expected, n * spp) + straddling * (2.0 / g) / n;
  EXPECT_NEAR(meanCovered(f, kR), expected, tol) << straddling << " straddling pixels";
  EXPECT_LT(expected, 0.97);  // the slab covers a visible part of the image
}

// A rough lobe over an open plane: every direction above the surface is
// open, so num = den for every sample and W is exactly 1 - at every
// roughness, from steep to grazing views (where much of a rough lobe lies
// below the surface: the normalisation over the part above it).
TEST(ReflOcc, OpenPlaneIsExactlyOne) {
  Scene scene;
  addPlane(scene, 1000.0f);
  scene.commit();
  for (float elevation : {80.0f, 45.0f, 10.0f, 1.0f, 0.05f}) {
    const float a = elevation * float(M_PI) / 180.0f;
    const Camera cam = makeLookAtCamera(Vec3(0, -10 * std::cos(a), 10 * std::sin(a)), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.3f, "c");
    for (const char* roughness : {"0", "1e-8", "0.5", "1", "-1"}) {
      SCOPED_TRACE(std::string("elevation ") + std::to_string(elevation) + ", roughness " + roughness);
      const Film f = renderWith(scene, cam, "reflocc", {std::string("roughness=") + roughness, "rays=4"}, passSettings(16, 16, 4));
      size_t covered = 0;
      for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
          if (f.at(kA, x, y) == 0.0f) continue;
          ++covered;
          EXPECT_EQ(f.at(kR, x, y), f.at(kA, x, y)) << x << "," << y;  // W = 1, premultiplied
        }
      EXPECT_GT(covered, 0u);
    }
  }
}

// 0/0: a shading normal tilted against the view sends the mirror direction
// below the geometric surface; at roughness 0 no direction of the pixel is
// above it, and the pixel is 1 (the core's convention, docs/math.md §12) -
// even under the slab, which the geometric mirror direction would meet.
TEST(ReflOcc, NoDirectionAboveTheSurfaceIsOne) {
  const MirrorScene geometry;
  Scene scene;
  const Vec3 ns = normalize(Vec3(0, -1, 0.01f));
  const float L = 50;
  scene.addWorldPrimitive({{-L, -L, 0}, {L, -L, 0}, {L, L, 0}, {-L, L, 0}}, {0, 1, 2, 0, 2, 3}, {ns, ns, ns, ns}, {}, -1);
  scene.addWorldPrimitive({{-1, 0.5f, 2}, {1, 0.5f, 2}, {1, 3, 2}, {-1, 3, 2}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene.commit();
  const int w = MirrorScene::kW, h = MirrorScene::kH;
  // Every view direction of the image mirrors to below the floor: r is
  // linear in d, and d is a positive multiple of an affine function of the
  // film position, so the sign of r_z over the image is decided at its corners.
  for (float fy : {0.0f, float(h)})
    for (float fx : {0.0f, float(w)}) {
      const Vec3 d = geometry.rc.direction(fx, fy);
      EXPECT_LT((d - ns * (2 * dot(d, ns))).z, -0.02f);
    }
  const Film f = renderWith(scene, geometry.cam, "reflocc", {"roughness=0", "rays=2"}, passSettings(w, h, 4));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) ASSERT_EQ(f.at(kR, x, y), 1.0f) << x << "," << y;
  // A rough lobe has directions above the surface again: finite, bounded.
  const Film g = renderWith(scene, geometry.cam, "reflocc", {"roughness=1", "rays=2"}, passSettings(w, h, 4));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) ASSERT_TRUE(g.at(kR, x, y) >= 0.0f && g.at(kR, x, y) <= 1.0f) << x << "," << y;
}

// --- an intermediate closed form: a ceiling at height H -----------------------
//
// A floor point below an infinite ceiling z = H: a direction w above the
// floor meets the ceiling at distance H / w_z, within R iff w_z >= c = H / R.
// With the lobe about r, cos(beta) = r_z, and w at angle alpha from r and
// azimuth phi about it, w_z = cos(alpha) cos(beta) + sin(alpha) sin(beta) cos(phi):
// the fraction of phi with w_z > t is acos((t - A)/B)/pi (A, B the two
// coefficients), so
//   W = Int g(alpha) [F(0) - F(c)] dalpha / Int g(alpha) F(0) dalpha,
//   g(alpha) = (m + 1) cos^m(alpha) sin(alpha),  F(t) = P_phi(w_z > t),
// by the midpoint rule in alpha (the lobe's density in alpha itself, not its
// sampling). Returns W and P(above) = Int g F(0).
struct CeilingRef {
  double W, above;
};
// The lobe's density in alpha on a midpoint grid, g(alpha_i) with cos and
// sin of alpha_i (independent of the view).
struct LobeTable {
  std::vector<double> g, ca, sa;
  explicit LobeTable(double roughness, int n = 5000) {
    const double a2 = std::pow(roughness, 4.0);
    const double m = (1 - a2) / (2 * a2);
    for (int i = 0; i < n; ++i) {
      const double al = (i + 0.5) * (M_PI / 2) / n;
      ca.push_back(std::cos(al)), sa.push_back(std::sin(al));
      g.push_back((m + 1) * std::pow(ca.back(), m) * sa.back());
    }
  }
};
CeilingRef ceilingReference(const LobeTable& t, double cosBeta, double c) {
  const double sinBeta = std::sqrt(std::max(0.0, 1 - cosBeta * cosBeta));
  const auto F = [](double A, double B, double x0) {
    if (B <= 0) return A > x0 ? 1.0 : 0.0;
    const double x = (x0 - A) / B;
    return x <= -1 ? 1.0 : x >= 1 ? 0.0 : std::acos(x) / M_PI;
  };
  double num = 0, den = 0, total = 0;
  for (size_t i = 0; i < t.g.size(); ++i) {
    const double A = t.ca[i] * cosBeta, B = t.sa[i] * sinBeta;
    const double f0 = F(A, B, 0.0);
    num += t.g[i] * (f0 - F(A, B, c));
    den += t.g[i] * f0;
    total += t.g[i];
  }
  return {num / den, den / total};
}

TEST(ReflOcc, CeilingWithinRMatchesQuadrature) {
  // Floor and ceiling of half-size 10: the floor's rays leave 10 * 2^-16
  // above it (core/scene/surface.h), so the ceiling is that much nearer.
  const double H = 1.0, R = 2.0;
  const double Heff = H - 10.0 * std::ldexp(1.0, -16);
  Scene scene;
  addPlane(scene, 10.0f);
  addPlane(scene, 10.0f, float(H));
  scene.commit();
  const int w = 16, spp = 64, rays = 4;
  for (double elevation : {60.0, 30.0, 10.0}) {  // of the view ray; r's angle from the vertical is 90 - this
    const double a = elevation * M_PI / 180;
    const float d = 0.5f;  // eye height, below the ceiling
    const Camera cam = makeLookAtCamera(Vec3(0, float(-d / std::tan(a)), d), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.05f, "c");
    const RasterCamera rc(cam, w, w);
    for (double roughness : {0.3, 0.5, 1.0}) {
      SCOPED_TRACE("elevation " + std::to_string(elevation) + ", roughness " + std::to_string(roughness));
      const LobeTable table(roughness);
      // Per pixel: the reference at its centre's view direction, and the
      // largest change to its corners (the footprint bound).
      double ref = 0, foot = 0, above = 0;
      for (int y = 0; y < w; ++y)
        for (int x = 0; x < w; ++x) {
          const auto at = [&](float fx, float fy) { return ceilingReference(table, -rc.direction(fx, fy).z, Heff / R); };
          const CeilingRef centre = at(x + 0.5f, y + 0.5f);
          double dev = 0;
          for (int cy = 0; cy <= 1; ++cy)
            for (int cx = 0; cx <= 1; ++cx) dev = std::max(dev, std::abs(at(float(x + cx), float(y + cy)).W - centre.W));
          ref += centre.W, foot += dev, above += centre.above;
        }
      const double n = double(w * w);
      ref /= n, foot /= n, above /= n;
      const Film f = renderWith(scene, cam, "reflocc",
                                {"roughness=" + formatFloat(roughness), "distance=" + formatFloat(R), "rays=" + std::to_string(rays)},
                                passSettings(w, w, spp));
      // A pixel's W is a ratio of counts over its ~spp x rays x P(above)
      // directions above the floor: binomial variance W(1 - W) over that
      // many; 4 standard errors of the mean over the pixels.
      const double se = bernoulliStdErr(ref, n * spp * rays * above);
      EXPECT_NEAR(meanCovered(f, kR), ref, 4 * se + foot) << "P(above) " << above;
    }
  }
}

// --- extremes -------------------------------------------------------------------

// Finite and in [0, 1] everywhere for roughness from 0 to 1, R from 10^-30
// to inf, steep and grazing views; R = 10^-30 reaches nothing (exactly 1)
// and R = 10^30 everything inf does (the same image, bit for bit).
TEST(ReflOcc, ExtremesStayFiniteAndBounded) {
  const MirrorScene s;
  const Camera grazing = makeLookAtCamera(Vec3(0, -40, 0.02f), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.2f, "grazing");
  for (const Camera* cam : {&s.cam, &grazing})
    for (const char* roughness : {"0", "1e-8", "1e-4", "0.5", "1"}) {
      std::vector<Film> films;
      for (const char* R : {"1e-30", "1e-3", "5.5", "1e30", "inf"}) {
        SCOPED_TRACE(std::string(cam->name) + ", roughness " + roughness + ", R " + R);
        films.push_back(renderWith(s.scene, *cam, "reflocc", {std::string("roughness=") + roughness, std::string("distance=") + R, "rays=2"},
                                   passSettings(16, 16, 4)));
        const Film& f = films.back();
        for (int y = 0; y < 16; ++y)
          for (int x = 0; x < 16; ++x) {
            const float v = f.at(kR, x, y), A = f.at(kA, x, y);
            ASSERT_TRUE(std::isfinite(v) && v >= 0.0f && v <= A) << x << "," << y << ": " << v;
            if (std::string(R) == "1e-30") {
              EXPECT_EQ(v, A) << x << "," << y;
            }
          }
      }
      for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) EXPECT_EQ(films[3].at(kR, x, y), films[4].at(kR, x, y));
    }
}

// Samples are keyed by pixel and sample index: the image is the same for any
// thread count and tile size.
TEST(ReflOcc, DeterministicAcrossThreadsAndTiles) {
  const MirrorScene s;
  RenderSettings a = passSettings(24, 16, 4), b = a;
  a.threads = 1, a.tileSize = 16;
  b.threads = 2, b.tileSize = 5;
  const Film fa = renderWith(s.scene, s.cam, "reflocc", {"roughness=0.4", "rays=3"}, a);
  const Film fb = renderWith(s.scene, s.cam, "reflocc", {"roughness=0.4", "rays=3"}, b);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 24; ++x) EXPECT_EQ(fa.at(kR, x, y), fb.at(kR, x, y));
}

TEST(ReflOcc, BadParametersAreRefusedNamingThem) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find("reflocc");
  const auto make = [&](std::vector<std::string> params) {
    ParamSet p(d.params, d.name);
    for (const auto& a : params) p.setAssignment(a);
    return d.create(p);
  };
  const auto message = [&](std::vector<std::string> params) {
    try {
      make(std::move(params));
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message({"roughness=-0.5"}).find("'roughness'"), std::string::npos);
  EXPECT_NE(message({"roughness=1.5"}).find("roughness"), std::string::npos);
  EXPECT_NE(message({"roughness=nan"}).find("roughness"), std::string::npos);
  EXPECT_NE(message({"near=3", "distance=2"}).find("'near'"), std::string::npos);
  EXPECT_EQ(message({"roughness=-1"}), "");
  // Only `near` of the lobe controls: `inside` and `spread` do not apply.
  EXPECT_NE(message({"spread=0.5"}).find("spread"), std::string::npos);
  // needs(): roughness from the material only when asked for.
  ParamSet p(d.params, d.name);
  EXPECT_TRUE(d.needs(p).roughness);
  p.set("roughness", "0.5");
  EXPECT_FALSE(d.needs(p).roughness);
  EXPECT_FALSE(d.needs(p).albedo);
}

// --- material roughness from glTF ------------------------------------------------

// The mirror scene as a glTF file: the floor (with uvs) carries material
// `floorMaterial` (null: none), the slab none.
std::string writeMirrorGltf(const std::string& dir, const std::string& name, const json& floorMaterial,
                            const std::function<void(GltfBuilder&)>& extra = nullptr) {
  GltfBuilder g;
  int mat = -1;
  if (!floorMaterial.is_null()) mat = g.push("materials", floorMaterial);
  const int floorMesh = g.quadMesh(50.0f, mat, true);
  // quadMesh(1) scaled to x in [-1, 1], y in [0.5, 3] at z = 2.
  const int slabMesh = g.quadMesh(1.0f);
  const int f = g.node({{"name", "floor"}, {"mesh", floorMesh}});
  const int s = g.node({{"name", "slab"}, {"mesh", slabMesh}, {"translation", {0, 1.75, 2}}, {"scale", {1, 1.25, 1}}});
  g.scene({f, s});
  if (extra) extra(g);
  return g.writeGltf(dir, name);
}

// A 4 x 4 16-bit RGB PNG of constant colour c, as textures[0] / images[0].
void addConstantTexture(GltfBuilder& g, const std::string& dir, Vec3 c, const std::string& file) {
  writeRgbTexture(dir + "/" + file, 4, 4, [c](double, double) { return c; });
  g.push("images", {{"uri", file}});
  g.push("samplers", {{"wrapS", 33071}, {"wrapT", 33071}});
  g.push("textures", {{"source", 0}, {"sampler", 0}});
}

Film renderMirror(const Scene& scene, const std::string& roughness) {
  const MirrorScene s;  // its camera
  return renderWith(scene, s.cam, "reflocc", {"roughness=" + roughness, "rays=2"}, passSettings(48, 32, 4));
}

void expectSameImage(const Film& a, const Film& b) {
  ASSERT_EQ(a.width(), b.width());
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x) ASSERT_EQ(a.at(kR, x, y), b.at(kR, x, y)) << x << "," << y;
}

// roughnessFactor x the G channel: a texture with G = 0 (R = B = 1, so
// reading another channel would show) makes any factor the mirror lobe, bit
// for bit; a factor alone, or glTF's default 1 (a material without
// pbrMetallicRoughness, or no material), equals that roughness given as a
// parameter, bit for bit (the same float reaches the same arithmetic).
TEST(ReflOccMaterial, RoughnessFactorTimesGreenChannel) {
  const std::string dir = tempDir("reflocc_material");
  const auto load = [&](const std::string& name, const json& material, bool texture = false, Vec3 c = Vec3(1, 0, 1)) {
    return loadGltf(writeMirrorGltf(dir, name, material, [&](GltfBuilder& g) {
      if (texture) addConstantTexture(g, dir, c, name + ".png");
    }));
  };
  const json textured = {{"pbrMetallicRoughness", {{"roughnessFactor", 0.7}, {"metallicRoughnessTexture", {{"index", 0}}}}}};
  expectSameImage(renderMirror(*load("g0", textured, true), "-1"), renderMirror(*load("plain", nullptr), "0"));
  const auto factorOnly = load("factor", {{"pbrMetallicRoughness", {{"roughnessFactor", 0.7}}}});
  expectSameImage(renderMirror(*factorOnly, "-1"), renderMirror(*factorOnly, "0.7"));
  const auto defaults = load("default", {{"name", "no pbr"}});
  expectSameImage(renderMirror(*defaults, "-1"), renderMirror(*defaults, "1"));
  const auto none = load("none", nullptr);
  expectSameImage(renderMirror(*none, "-1"), renderMirror(*none, "1"));
  // And the factor matters: 0.7 is not the mirror.
  const Film a = renderMirror(*factorOnly, "0.7"), b = renderMirror(*factorOnly, "0");
  EXPECT_GT(std::abs(meanCovered(a, kR) - meanCovered(b, kR)), 0.01);
}

// The texture is linear data: G = 0.5 (16-bit) reads as 32768/65535, not as
// the sRGB decode 0.214. The lookup's bilinear arithmetic may round the
// product by an ulp, which moves a direction by ~1e-7 rad and can flip a
// sample only that close to the slab's edge: the two renders share every
// sample, so their means agree far inside the gap to the sRGB reading.
TEST(ReflOccMaterial, TextureIsLinearNotSrgb) {
  const std::string dir = tempDir("reflocc_linear");
  const json textured = {{"pbrMetallicRoughness", {{"metallicRoughnessTexture", {{"index", 0}}}}}};
  const auto scene = loadGltf(writeMirrorGltf(dir, "half", textured, [&](GltfBuilder& g) {
    addConstantTexture(g, dir, Vec3(0.25f, 0.5f, 0.75f), "half.png");
  }));
  ASSERT_EQ(scene->dataTextures.size(), 1u);
  EXPECT_TRUE(scene->textures.empty());  // not a colour texture: never decoded for albedo
  const double g = 32768.0 / 65535.0;
  const Film tex = renderMirror(*scene, "-1"), linear = renderMirror(*scene, formatFloat(g)),
             srgb = renderMirror(*scene, formatFloat(std::pow((g + 0.055) / 1.055, 2.4)));
  // Mean per-pixel differences: 8 samples a pixel, so one flipped sample
  // in the whole image is 1/8 / (48 x 32) = 8e-5.
  const auto meanAbsDiff = [](const Film& a, const Film& b) {
    double d = 0;
    for (int y = 0; y < a.height(); ++y)
      for (int x = 0; x < a.width(); ++x) d += std::abs(double(a.at(kR, x, y)) - b.at(kR, x, y));
    return d / (a.width() * a.height());
  };
  EXPECT_LT(meanAbsDiff(tex, linear), 2e-4);
  EXPECT_GT(meanAbsDiff(srgb, linear), 0.01);
}

// One image as base colour (sRGB) and metallicRoughness (linear): two
// textures, each decoded its own way; a texture on TEXCOORD_1 is ignored
// with a warning (the factor alone), as for the base colour.
TEST(ReflOccMaterial, SharedImageAndTexCoord) {
  const std::string dir = tempDir("reflocc_shared");
  const json both = {{"pbrMetallicRoughness",
                      {{"baseColorTexture", {{"index", 0}}}, {"metallicRoughnessTexture", {{"index", 0}}}}}};
  const auto scene = loadGltf(writeMirrorGltf(dir, "both", both, [&](GltfBuilder& g) {
    addConstantTexture(g, dir, Vec3(0.5f, 0.5f, 0.5f), "both.png");
  }));
  ASSERT_EQ(scene->textures.size(), 1u);
  ASSERT_EQ(scene->dataTextures.size(), 1u);
  scene->textures[0]->decode();
  scene->dataTextures[0]->decode();
  const float colour = scene->textures[0]->sample(0.5f, 0.5f, WrapMode::ClampToEdge, WrapMode::ClampToEdge).y;
  const float data = scene->dataTextures[0]->sample(0.5f, 0.5f, WrapMode::ClampToEdge, WrapMode::ClampToEdge).y;
  EXPECT_NEAR(data, 32768.0 / 65535.0, 1e-6);
  EXPECT_NEAR(colour, srgbToLinear(32768.0f / 65535.0f), 1e-6);

  WarningCapture w;
  const json coord1 = {{"pbrMetallicRoughness", {{"roughnessFactor", 0.6}, {"metallicRoughnessTexture", {{"index", 0}, {"texCoord", 1}}}}}};
  const auto c1 = loadGltf(writeMirrorGltf(dir, "coord1", coord1, [&](GltfBuilder& g) {
    addConstantTexture(g, dir, Vec3(0, 0, 0), "coord1.png");
  }));
  EXPECT_EQ(w.count("TEXCOORD_1"), 1u) << w.all();
  EXPECT_EQ(c1->materials[0].roughnessTexture, -1);
  expectSameImage(renderMirror(*c1, "-1"), renderMirror(*c1, "0.6"));
}

// A corrupt metallicRoughness image: the render fails with one error naming
// the image (decoded on first use, in a render thread: the error reaches the
// caller), never a crash.
TEST(ReflOccMaterial, CorruptTextureIsAnError) {
  const std::string dir = tempDir("reflocc_corrupt");
  const json textured = {{"pbrMetallicRoughness", {{"metallicRoughnessTexture", {{"index", 0}}}}}};
  const auto scene = loadGltf(writeMirrorGltf(dir, "corrupt", textured, [&](GltfBuilder& g) {
    writeText(dir + "/broken.png", "not a png");
    g.push("images", {{"uri", "broken.png"}});
    g.push("textures", {{"source", 0}});
  }));
  try {
    renderMirror(*scene, "-1");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("broken.png"), std::string::npos) << e.what();
  }
  // An integrator that reads no roughness never decodes it.
  const MirrorScene s;
  EXPECT_NO_THROW(renderWith(*scene, s.cam, "reflocc", {"roughness=0.5"}, passSettings(8, 8, 1)));
  RenderSettings withAovs = passSettings(8, 8, 1);
  withAovs.aovs = true;  // decodes the colour textures (there are none), not the data ones
  EXPECT_NO_THROW(renderWith(*scene, s.cam, "ao", {}, withAovs));
}

// Model only what is needed: the metallicRoughness image stays encoded
// through an AO render with AOVs (which decodes the colour textures) and a
// reflocc render with a roughness parameter; reading the material decodes it.
TEST(ReflOccMaterial, RoughnessTexturesAreDecodedOnlyWhenRead) {
  const std::string dir = tempDir("reflocc_needs");
  const json textured = {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}, {"metallicRoughnessTexture", {{"index", 0}}}}}};
  const auto scene = loadGltf(writeMirrorGltf(dir, "needs", textured, [&](GltfBuilder& g) {
    addConstantTexture(g, dir, Vec3(0.5f, 0.5f, 0.5f), "needs.png");
  }));
  ASSERT_EQ(scene->dataTextures.size(), 1u);
  const MirrorScene s;
  RenderSettings withAovs = passSettings(8, 8, 1);
  withAovs.aovs = true;
  renderWith(*scene, s.cam, "ao", {}, withAovs);
  EXPECT_TRUE(scene->textures[0]->decoded());
  renderWith(*scene, s.cam, "reflocc", {"roughness=0.5"}, withAovs);
  EXPECT_FALSE(scene->dataTextures[0]->decoded());
  renderWith(*scene, s.cam, "reflocc", {}, passSettings(8, 8, 1));
  EXPECT_TRUE(scene->dataTextures[0]->decoded());
}

// Bad material fields: one error naming the file and the field.
TEST(ReflOccMaterial, BadFieldsAreRefusedNamingThem) {
  const std::string dir = tempDir("reflocc_bad");
  const std::string pbr = "materials[0].pbrMetallicRoughness.";
  struct Case {
    const char* name;
    json material;
    std::string field;
    bool texture;
  };
  const std::vector<Case> cases = {
      {"above1", {{"pbrMetallicRoughness", {{"roughnessFactor", 1.5}}}}, pbr + "roughnessFactor", false},
      {"negative", {{"pbrMetallicRoughness", {{"roughnessFactor", -0.25}}}}, pbr + "roughnessFactor", false},
      {"string", {{"pbrMetallicRoughness", {{"roughnessFactor", "0.5"}}}}, pbr + "roughnessFactor", false},
      {"metallic", {{"pbrMetallicRoughness", {{"metallicFactor", {1}}}}}, pbr + "metallicFactor", false},
      {"notobject", {{"pbrMetallicRoughness", {{"metallicRoughnessTexture", 0}}}}, pbr + "metallicRoughnessTexture", false},
      {"badindex", {{"pbrMetallicRoughness", {{"metallicRoughnessTexture", {{"index", 3}}}}}}, pbr + "metallicRoughnessTexture.index", true},
      {"strindex", {{"pbrMetallicRoughness", {{"metallicRoughnessTexture", {{"index", "0"}}}}}}, pbr + "metallicRoughnessTexture.index", true},
      {"texcoord", {{"pbrMetallicRoughness", {{"metallicRoughnessTexture", {{"index", 0}, {"texCoord", -1}}}}}},
       pbr + "metallicRoughnessTexture.texCoord", true},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string path = writeMirrorGltf(dir, c.name, c.material, [&](GltfBuilder& g) {
      if (c.texture) addConstantTexture(g, dir, Vec3(1, 1, 1), std::string(c.name) + ".png");
    });
    try {
      loadGltf(path);
      ADD_FAILURE() << "accepted";
    } catch (const Error& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.rfind(path + ": " + c.field + ":", 0), 0u) << m;
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    }
  }
}

// The CLI: the default reads the material, and equals the parameter.
TEST(ReflOccMaterial, CliRendersMaterialRoughness) {
  const std::string dir = tempDir("reflocc_cli");
  const std::string scene = writeMirrorGltf(dir, "cli", {{"pbrMetallicRoughness", {{"roughnessFactor", 0.4}}}}, [](GltfBuilder& g) {
    g.push("cameras", perspective("cam", 0.5, 0.01));
    // At (0, -6, 1) looking along +y, tilted 18.4 degrees down (a rotation about x).
    const double t = std::atan2(1.0, 3.0) / 2, s = std::sin(M_PI / 4 - t), c = std::cos(M_PI / 4 - t);
    g.doc["scenes"][0]["nodes"].push_back(g.node({{"camera", 0}, {"translation", {0, -6, 1}}, {"rotation", {s, 0, 0, c}}}));
  });
  const std::vector<std::string> common = {"render", scene, "--res", "24x16", "--spp", "4", "-q", "-i", "reflocc"};
  auto a = common, b = common;
  a.insert(a.end(), {"-o", dir + "/material.exr"});
  b.insert(b.end(), {"-o", dir + "/param.exr", "-p", "roughness=0.4"});
  const auto results = runClis({a, b}, dir);
  for (const CliResult& r : results) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack ma = readExr(dir + "/material.exr"), pa = readExr(dir + "/param.exr");
  ASSERT_TRUE(ma.ok && pa.ok);
  EXPECT_EQ(ma.planes.at("R"), pa.planes.at("R"));
  double sum = 0;
  for (float v : ma.planes.at("R")) sum += v;
  EXPECT_LT(sum / double(ma.planes.at("R").size()), 0.999);  // the slab is in the reflections
}

}  // namespace
}  // namespace obscura::test
