// The EXR as compositors read it (docs/exr.md "Depth and camera conventions"):
// the OpenEXR standard camera matrices rebuild the render's projection from
// the header alone, Z is camera-plane depth with a finite background, depth
// and normals stay 32-bit under --half, the chromaticities are Rec.709, and
// outputs whose extension is not the format written are refused.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "core/image/image_io.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

using D3 = std::array<double, 3>;

// A matrix attribute of the header (row-vector form, 16 floats).
std::array<double, 16> headerMatrix(const OIIO::ImageSpec& spec, const char* name) {
  std::array<double, 16> m{};
  const OIIO::ParamValue* p = spec.find_attribute(name, OIIO::TypeMatrix44);
  EXPECT_NE(p, nullptr) << name;
  if (!p) return m;
  const float* f = static_cast<const float*>(p->data());
  for (size_t i = 0; i < 16; ++i) m[i] = double(f[i]);
  return m;
}

// p' = [p 1] M in homogeneous coordinates (row-vector form, as EXR stores it).
std::array<double, 4> transformRow(const std::array<double, 16>& m, D3 p) {
  std::array<double, 4> r{};
  for (size_t j = 0; j < 4; ++j) r[j] = p[0] * m[0 * 4 + j] + p[1] * m[1 * 4 + j] + p[2] * m[2 * 4 + j] + m[3 * 4 + j];
  return r;
}

// Rotation of v by the unit quaternion q = (x, y, z, w) (glTF's order).
D3 rotate(const std::array<double, 4>& q, D3 v) {
  const D3 u{q[0], q[1], q[2]};
  const double w = q[3];
  const auto cross = [](D3 a, D3 b) { return D3{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; };
  const D3 t = cross(u, v);
  const D3 t2{2 * t[0], 2 * t[1], 2 * t[2]};
  const D3 c = cross(u, t2);
  return {v[0] + w * t2[0] + c[0], v[1] + w * t2[1] + c[1], v[2] + w * t2[2] + c[2]};
}

std::array<double, 4> axisAngle(D3 axis, double angle) {
  const double l = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  const double s = std::sin(0.5 * angle) / l;
  return {axis[0] * s, axis[1] * s, axis[2] * s, std::cos(0.5 * angle)};
}

// A small square facing the camera squarely: its image is a square too (a
// plane parallel to the image plane projects by a uniform scale), so the
// centroid of its coverage is the image of its centre.
struct FacingQuad {
  double x, y, depth, half;  // centre in the camera's frame (x right, y up, depth ahead), half-size
};

// An off-axis camera (rotated about a slanted axis, away from the origin)
// and three facing quads at different depths and image positions, rendered
// through the CLI at a non-square resolution; the header's worldToNDC
// projects each quad's centre onto the centroid of its coverage in A, within
// the discretization bound the image itself gives plus 3 standard errors of
// the coverage estimate. The same matrices give each quad's depth, which is
// the Z the render holds.
TEST(ExrConventions, HeaderMatricesProjectScenePointsOntoTheirPixels) {
  const std::string dir = tempDir("exr_conventions_camera");
  const int W = 160, H = 90, spp = 64;
  const double yfov = 0.6;
  const D3 eye{2.0, 1.5, 6.0};
  const std::array<double, 4> q = axisAngle({0.3, 1.0, 0.15}, 0.6);
  const std::vector<FacingQuad> quads = {{-1.2, 0.6, 4.0, 0.25}, {1.5, -0.8, 6.0, 0.3}, {0.1, 0.1, 2.5, 0.12}};

  GltfBuilder g;
  g.push("cameras", perspective("offaxis", yfov, 0.05));
  std::vector<int> roots;
  std::vector<D3> centres;
  for (const FacingQuad& f : quads) {
    // glTF's camera looks down its -Z: the centre is at (x, y, -depth) in
    // the camera node's frame; the quad's node shares the camera's rotation.
    const D3 o = rotate(q, {f.x, f.y, -f.depth});
    centres.push_back({eye[0] + o[0], eye[1] + o[1], eye[2] + o[2]});
    roots.push_back(g.node({{"mesh", g.quadMesh(float(f.half))},
                            {"translation", {centres.back()[0], centres.back()[1], centres.back()[2]}},
                            {"rotation", {q[0], q[1], q[2], q[3]}}}));
  }
  roots.push_back(g.node({{"camera", 0}, {"translation", {eye[0], eye[1], eye[2]}}, {"rotation", {q[0], q[1], q[2], q[3]}}}));
  g.scene(roots);
  const std::string scene = g.writeGltf(dir, "quads");
  const std::string out = dir + "/quads.exr";
  const CliResult cli = runCli({"render", scene, "-o", out, "--res", std::to_string(W) + "x" + std::to_string(H), "--spp",
                                std::to_string(spp), "--seed", "3", "-p", "rays=1", "--quiet"},
                               dir + "/stderr.txt");
  ASSERT_EQ(cli.exitCode, 0) << cli.stderrText;
  const ReadBack r = readExr(out);
  ASSERT_TRUE(r.ok);
  const auto w2c = headerMatrix(r.spec, "worldToCamera");
  const auto w2ndc = headerMatrix(r.spec, "worldToNDC");
  const std::vector<float>& A = r.planes.at("A");
  const std::vector<float>& Z = r.planes.at("Z");

  // The standard camera frame: left-handed (the 3x3 part has determinant
  // -1 from glTF's right-handed world), and its inverse puts the camera at
  // the node's position: p0 = -t R^T for p' = p R + t.
  const auto det3 = w2c[0] * (w2c[5] * w2c[10] - w2c[6] * w2c[9]) - w2c[1] * (w2c[4] * w2c[10] - w2c[6] * w2c[8]) +
                    w2c[2] * (w2c[4] * w2c[9] - w2c[5] * w2c[8]);
  EXPECT_NEAR(det3, -1.0, 1e-5);
  for (int k = 0; k < 3; ++k) {
    const double p0 = -(w2c[12] * w2c[size_t(k * 4 + 0)] + w2c[13] * w2c[size_t(k * 4 + 1)] + w2c[14] * w2c[size_t(k * 4 + 2)]);
    EXPECT_NEAR(p0, eye[size_t(k)], 1e-5 * 8) << "camera position, axis " << k;  // float matrix entries of size ~8
  }
  const double fovH = r.spec.get_float_attribute("obscura:fovHorizontal", -1) * M_PI / 180.0;
  const double fovV = r.spec.get_float_attribute("obscura:fovVertical", -1) * M_PI / 180.0;
  EXPECT_NEAR(fovV, yfov, 1e-6);
  EXPECT_NEAR(std::tan(0.5 * fovH), std::tan(0.5 * yfov) * W / H, 1e-6);

  for (size_t i = 0; i < quads.size(); ++i) {
    SCOPED_TRACE("quad " + std::to_string(i));
    const FacingQuad& f = quads[i];
    // Camera space by the header: +Z ahead, so the depth is z.
    const auto c = transformRow(w2c, centres[i]);
    EXPECT_NEAR(c[0], f.x, 1e-5 * 8);
    EXPECT_NEAR(c[1], f.y, 1e-5 * 8);
    EXPECT_NEAR(c[2], f.depth, 1e-5 * 8);
    // NDC by the header, and the same point from worldToCamera and the field
    // of view attributes (how a compositor without worldToNDC rebuilds it).
    const auto h = transformRow(w2ndc, centres[i]);
    const double u = h[0] / h[3], v = h[1] / h[3];
    EXPECT_NEAR(u, 0.5 * (c[0] / (c[2] * std::tan(0.5 * fovH)) + 1.0), 1e-5);
    EXPECT_NEAR(v, 0.5 * (1.0 - c[1] / (c[2] * std::tan(0.5 * fovV))), 1e-5);
    const double px = u * W, py = v * H;  // NDC (0,0)..(1,1) = the image's corners
    // The quad's image: a square of side s pixels about (px, py).
    const double s = 2.0 * f.half / (f.depth * std::tan(0.5 * yfov)) * 0.5 * H;
    const int x0 = int(std::floor(px - 0.5 * s - 3)), x1 = int(std::ceil(px + 0.5 * s + 3));
    const int y0 = int(std::floor(py - 0.5 * s - 3)), y1 = int(std::ceil(py + 0.5 * s + 3));
    ASSERT_TRUE(x0 >= 0 && y0 >= 0 && x1 <= W && y1 <= H) << "window off the image";
    double sumA = 0, sx = 0, sy = 0, partialA = 0, varA = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        const double a = A[size_t(y) * W + size_t(x)];
        sumA += a, sx += a * (x + 0.5), sy += a * (y + 0.5);
        if (a > 0 && a < 1) partialA += a;
        varA += a * (1 - a) / spp;  // Bernoulli variance of a pixel's coverage (stratified sampling has less)
        // Covered pixels see only this quad, at its camera-plane depth.
        if (a > 0) EXPECT_NEAR(Z[size_t(y) * W + size_t(x)], f.depth, 1e-5 * f.depth) << x << "," << y;
      }
    ASSERT_GT(sumA, 0.0) << "nothing rendered where the header projects the quad";
    // Coverage in the window is the square's area (the header's scale is the
    // render's), within 3 standard errors.
    EXPECT_NEAR(sumA, s * s, 3 * std::sqrt(varA) + 1e-9);
    const double cx = sx / sumA, cy = sy / sumA;
    // Weighting pixel centres by coverage moves the centroid only through
    // partly covered pixels, each by at most half a pixel per axis; the
    // coverage noise moves it by sqrt(sum var(A_p) d_p^2) / sumA, bounded
    // with d_p <= the window's half-diagonal.
    const double halfDiag = 0.5 * std::hypot(double(x1 - x0), double(y1 - y0));
    const double tol = 0.5 * partialA / sumA + 3 * std::sqrt(varA) * halfDiag / sumA;
    EXPECT_NEAR(cx, px, tol);
    EXPECT_NEAR(cy, py, tol);
    std::printf("quad %zu: header (%.3f, %.3f), render (%.3f, %.3f), tolerance %.3f px\n", i, px, py, cx, cy, tol);
  }
  EXPECT_EQ(r.spec.get_string_attribute("obscura:upAxis"), "+Y");
}

// Z is the distance along the view axis, not along the ray: a plane
// perpendicular to the axis at distance D reads D in every covered pixel,
// also at the image's corners, where the ray distance is up to 21% longer.
// The ray-traced loop and the G-buffer loop (a screen-space integrator)
// agree. Where nothing is hit Z is the finite kBackgroundDepth. The
// tolerance: t, the unit ray and its cosine to the axis each carry a few
// float roundings (2^-24 relative).
TEST(ExrConventions, ZIsCameraPlaneDepthAndTheBackgroundIsFinite) {
  Scene scene;
  addPlane(scene, 1.5f);  // x in [-1.5, 1.5]: the image's sides are background
  scene.commit();
  const float D = 3.0f;
  const Camera cam = makeLookAtCamera(Vec3(0, 0, D), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.9f, "c");
  for (const char* integrator : {"ao", "vo"}) {
    SCOPED_TRACE(integrator);
    RenderSettings s = passSettings(48, 32, 4, 5);
    s.aovs = true;
    const Film f = renderWith(scene, cam, integrator, {}, s);
    int covered = 0, background = 0;
    double longestRay = 0;
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 48; ++x) {
        const float z = f.at(kZ, x, y);
        ASSERT_TRUE(std::isfinite(z));
        if (f.at(kA, x, y) == 0.0f) {
          EXPECT_EQ(z, kBackgroundDepth);
          ++background;
          continue;
        }
        ++covered;
        EXPECT_NEAR(z, D, 1e-5f * D) << x << "," << y;
        Vec3 org, dir;
        cam.generateRay(float(x) + 0.5f, float(y) + 0.5f, 48, 32, org, dir);
        longestRay = std::max(longestRay, double(D) / double(-dir.z));
      }
    EXPECT_GT(covered, 500);
    EXPECT_GT(background, 100);
    EXPECT_GT(longestRay, 1.15 * D);  // the test tells depth from ray distance
  }
}

// --half keeps N and Z 32-bit and everything else half, extra planes too
// unless listed in floatChannelPrefixes; the float channels round-trip exactly (a
// depth of 1234.5678 and the 1e10 background have no half: 1234 or 1235,
// and +inf).
TEST(ExrConventions, HalfKeepsDepthAndNormalsFloat) {
  const std::string dir = tempDir("exr_conventions_half");
  Film film(4, 2, true);
  const int pass = film.addPlane("dirt.R");
  const int id = film.addPlane("ids.R");
  for (int c : film.channels())
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 4; ++x) film.at(c, x, y) = 0.333333f + 0.01f * float(c) + 0.001f * float(x + 4 * y);
  film.at(kZ, 0, 0) = 1234.5678f;
  film.at(kZ, 1, 0) = kBackgroundDepth;
  film.at(kNX, 2, 1) = 0.123456789f;
  film.at(id, 3, 1) = 3.0e-20f;  // an ID-like value far below half's range
  ExrOptions o;
  o.half = true;
  o.floatChannelPrefixes = {"ids.R"};
  writeExr(dir + "/h.exr", film, o);
  const ReadBack r = readExr(dir + "/h.exr");
  ASSERT_TRUE(r.ok);
  ASSERT_EQ(r.spec.channelformats.size(), size_t(r.spec.nchannels));
  for (int i = 0; i < r.spec.nchannels; ++i) {
    const std::string& name = r.spec.channelnames[size_t(i)];
    const bool keep = name == "Z" || name == "N.X" || name == "N.Y" || name == "N.Z" || name == "ids.R";
    EXPECT_EQ(r.spec.channelformats[size_t(i)], keep ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::HALF) << name;
    const int c = film.find(name);
    ASSERT_GE(c, 0) << name;
    const std::vector<float>& p = r.planes.at(name);
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 4; ++x) {
        const float v = film.at(c, x, y);
        if (keep) EXPECT_EQ(p[size_t(y) * 4 + x], v) << name;
        else EXPECT_NEAR(p[size_t(y) * 4 + x], v, std::abs(v) * 0x1p-11f) << name;  // half: 11-bit significand
      }
  }
  EXPECT_NE(film.at(pass, 0, 0), 0.0f);
  // Without --half every channel is float.
  writeExr(dir + "/f.exr", film, {});
  const ReadBack f = readExr(dir + "/f.exr");
  EXPECT_EQ(f.spec.format, OIIO::TypeDesc::FLOAT);
  for (const OIIO::TypeDesc& t : f.spec.channelformats) EXPECT_EQ(t, OIIO::TypeDesc::FLOAT);
}

// The standard chromaticities attribute: Rec.709 primaries and D65 white
// (ITU-R BT.709 CIE xy), on every EXR written; and the CLI's header says
// what Z and N are and the background's Z.
TEST(ExrConventions, ChromaticitiesAndChannelMeaningsInTheHeader) {
  const std::string dir = tempDir("exr_conventions_header");
  // One quad and no camera: the automatic one frames it, background around.
  GltfBuilder g;
  g.node({{"mesh", g.quadMesh(1.0f)}});
  g.scene({0});
  const CliResult cli = runCli({"render", g.writeGltf(dir, "quad"), "-o", dir + "/a.exr", "--res", "32x18", "--spp", "1",
                                "--half", "--quiet"},
                               dir + "/stderr.txt");
  ASSERT_EQ(cli.exitCode, 0) << cli.stderrText;
  const ReadBack r = readExr(dir + "/a.exr");
  ASSERT_TRUE(r.ok);
  const OIIO::ParamValue* c = r.spec.find_attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8));
  ASSERT_NE(c, nullptr);
  const float* xy = static_cast<const float*>(c->data());
  const float rec709[8] = {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f};
  for (int i = 0; i < 8; ++i) EXPECT_EQ(xy[i], rec709[i]) << i;
  EXPECT_EQ(r.spec.get_float_attribute("obscura:backgroundZ"), kBackgroundDepth);
  EXPECT_NE(r.spec.get_string_attribute("obscura:Z").find("camera-plane depth"), std::string::npos);
  EXPECT_NE(r.spec.get_string_attribute("obscura:N").find("+Y up"), std::string::npos);
  EXPECT_GT(r.spec.get_float_attribute("obscura:clipFar"), r.spec.get_float_attribute("obscura:clipNear"));
  // Background pixels hold the documented value; under --half too.
  size_t background = 0;
  for (size_t i = 0; i < r.planes.at("A").size(); ++i)
    if (r.planes.at("A")[i] == 0.0f) {
      EXPECT_EQ(r.planes.at("Z")[i], kBackgroundDepth);
      ++background;
    }
  EXPECT_GT(background, 0u);
}

// An output whose extension is not what is written is refused before any
// work, with one line naming the option: the scene path does not even
// exist, and nothing is written. Case does not matter.
TEST(ExrConventions, MismatchedExtensionsAreRefused) {
  const std::string dir = tempDir("exr_conventions_ext");
  const std::string missing = dir + "/no_such_scene.gltf";
  struct Case {
    std::vector<std::string> args;
    std::string option;
  };
  const std::vector<Case> cases = {
      {{"-o", dir + "/out.tif"}, "-o "},
      {{"-o", dir + "/out.exr.png"}, "-o "},
      {{"-o", dir + "/out.exr", "--preview", dir + "/p.jpg"}, "--preview "},
      {{"-o", dir + "/out.exr", "--preview", dir + "/p.exr"}, "--preview "},
  };
  std::vector<std::vector<std::string>> runs;
  for (const Case& c : cases) {
    runs.push_back({"render", missing, "--quiet"});
    runs.back().insert(runs.back().end(), c.args.begin(), c.args.end());
  }
  const std::vector<CliResult> results = runClis(runs, dir);
  for (size_t i = 0; i < cases.size(); ++i) {
    const CliResult& cli = results[i];
    EXPECT_NE(cli.exitCode, 0) << i;
    EXPECT_EQ(cli.signal, 0) << i;
    EXPECT_EQ(std::count(cli.stderrText.begin(), cli.stderrText.end(), '\n'), 1) << cli.stderrText;
    EXPECT_NE(cli.stderrText.find("error: " + cases[i].option), std::string::npos) << cli.stderrText;
    EXPECT_EQ(cli.stderrText.find("no_such_scene"), std::string::npos) << "checked after the scene: " << cli.stderrText;
  }
  size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files += e.path().filename().string().rfind("stderr", 0) != 0;
  EXPECT_EQ(files, 0u);
  const CliResult ok = runCli({"render", "-o", dir + "/OUT.EXR", "--preview", dir + "/P.Png", "--res", "8x8", "--spp", "1",
                               "--quiet"},
                              dir + "/stderr_ok.txt");
  ASSERT_EQ(ok.exitCode, 0) << ok.stderrText;
  EXPECT_TRUE(std::filesystem::exists(dir + "/OUT.EXR"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/P.Png"));
}

}  // namespace
}  // namespace obscura::test
