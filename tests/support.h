// Shared helpers for the test suite: scenes built in code, renders in
// process, statistics for tolerances derived from sample counts, files and
// images on disk, captured warnings, and the CLI run as a child process.
#pragma once

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <sys/types.h>

#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/scene/camera.h"
#include "core/image/film.h"
#include <obscura/integrator.h>
#include "core/render/render.h"
#include "core/scene/scene.h"
#include "core/subd/subdivision.h"

namespace obscura::test {

// This build's paths, compiled into tests/paths.cpp alone: every other test
// file then compiles to the same object in every clone, which a compiler
// cache keyed without the clone's path reuses (docs/testing.md "Build times").
const char* sourceDir();         // the checkout
const char* obscuraBinary();     // the obscura program of this build
const char* defaultScenesDir();  // ../shared/scenes beside the checkout
// sourceDir() + "/" + rel.
std::string sourcePath(const std::string& rel);

// A fresh, empty directory under the build tree's temp area for one test.
std::string tempDir(const std::string& name);

// --- the third-party scenes (not in the repository) -------------------------
// They live in one folder: $OBSCURA_SCENES if set, else ../shared/scenes beside
// the checkout (defaultScenesDir()). A test
// that needs them calls OBSCURA_NEED_SHARED_SCENE(path): when the file is
// absent the test is skipped with one line naming it and why, unless
// OBSCURA_REQUIRE_SCENES=1 (set by .ci/run), which turns the skip into a
// failure so CI always runs them.
std::string sharedScenesDir();
// sharedScenesDir() + "/" + rel.
std::string sharedScene(const std::string& rel);
// True when OBSCURA_REQUIRE_SCENES is set to a non-empty value other than 0.
bool sharedScenesRequired();
// Whether a test that needs an outside client (headless Chromium, Blender)
// must fail rather than skip where it is absent: in CI (.ci/run sets
// OBSCURA_REQUIRE_SCENES; CI=true as well), whose setup.sh installs them.
bool clientsRequired();
// "" if `path` exists, else the one-line reason the test cannot run.
std::string missingSharedScene(const std::string& path);

#define OBSCURA_NEED_SHARED_SCENE(path)                                              \
  do {                                                                               \
    const std::string obscuraMissing_ = ::obscura::test::missingSharedScene(path);   \
    if (!obscuraMissing_.empty()) {                                                  \
      if (::obscura::test::sharedScenesRequired()) FAIL() << obscuraMissing_;       \
      GTEST_SKIP() << obscuraMissing_;                                               \
    }                                                                                \
  } while (0)

// Triangle list of a sphere of radius rs about the origin, normals facing the
// centre (seen from inside), with the polar cap of half-angle alpha about +Z
// removed (docs/math.md §7); alpha = 0 gives the closed sphere. `rings`
// latitude bands from the hole edge to the -Z pole, `segments` around;
// vertex normals are exact (-p/rs).
// The same triangles as position, normal and index lists.
void sphereCavityMesh(float rs, double alpha, int rings, int segments, std::vector<Vec3>& pos, std::vector<Vec3>& nrm,
                      std::vector<uint32_t>& idx);

// `material` indexes scene.materials (-1 = the default, albedo 1).
void addSphereCavity(Scene& scene, float rs, double alpha, int rings, int segments, int material = -1);

// Appends a grey material of albedo a with no texture and returns its index.
int addGreyMaterial(Scene& scene, float a);

// One closest-hit ray through the scene's BVH: the traced RayHit
// (hit.geomID = RTC_INVALID_GEOMETRY_ID on a miss).
RayHit traceClosest(const Scene& scene, Vec3 org, Vec3 dir);

// A square in the plane z = 0, side 2*halfSize, normal +Z.
void addPlane(Scene& scene, float halfSize, float z = 0.0f);

// The unit square [0,1]^2 in the plane z = 0 as an n x n grid of quads, with
// texture coordinates uv = xy: a subdivision cage whose limit is the square.
SubdivisionCage planeCage(int n);

// Settings for a pass-only render (no AOVs) of w x h pixels at spp.
RenderSettings passSettings(int w, int h, int spp, uint32_t seed = 0);

// The integrator `name` configured by "key=value" strings.
std::unique_ptr<Integrator> makeIntegrator(const std::string& name, const std::vector<std::string>& params);

// Renders with `integrator` configured by "key=value" strings.
Film renderWith(const Scene& scene, const Camera& camera, const std::string& integrator,
                const std::vector<std::string>& params, const RenderSettings& settings,
                RenderStats* stats = nullptr);

// Mean of channel c over pixels whose coverage A is 1 (fully covered).
double meanCovered(const Film& film, int channel, size_t* count = nullptr);

// Statistics of channel c over fully covered pixels. Pixels are independent
// estimates (each has its own scramble seed), so the standard error of
// their mean is their sample standard deviation / sqrt(n).
struct PixelStats {
  double mean = 0, sd = 0, se = 0, kurtosis = 0;  // kurtosis = m4 / m2^2
  size_t n = 0;
};
PixelStats pixelStats(const Film& film, int c);

// Asserts that two films hold the same planes (names, order, window) with
// the same bits in every pixel; `what` names the comparison in failures.
void expectSameFilm(const Film& a, const Film& b, const std::string& what);

// Form factor from a floor point (normal +z) at the origin to the rectangle
// [0, X] x [0, Y] parallel to the floor at height h: (1 / 2 pi) [A / sqrt(1 + A^2)
// atan(B / sqrt(1 + A^2)) + B / sqrt(1 + B^2) atan(A / sqrt(1 + B^2))], A = X / h,
// B = Y / h. Odd in X and in Y, so a signed sum of four gives any rectangle.
double cornerFormFactor(double X, double Y, double h);
// The rectangle [x0, x1] x [y0, y1] at height h, seen from floor point (px, py).
double rectFormFactor(double x0, double x1, double y0, double y1, double h, double px = 0, double py = 0);

// Standard error of the mean of n Bernoulli(p) draws.
inline double bernoulliStdErr(double p, double n) { return std::sqrt(std::max(p * (1 - p), 1e-12) / n); }

// The cube [-1, 1]^3 as a cage of six outward quads.
SubdivisionCage cubeCage();

// From a point inside a closed surface no AO ray escapes (watertight
// traversal, so `scene` should be robust): every pixel of a render from
// `eye` towards `target` is exactly 0.
void expectNoRayEscapes(const Scene& scene, Vec3 eye = Vec3(0.1f, -0.05f, 0.02f), Vec3 target = Vec3(1, 0.3f, 0.2f));
// The same for a refined mesh, as one robust world-space primitive.
void expectNoRayEscapes(const SubdividedMesh& m);

// --- screen-space passes (tests/test_screen_space*.cpp) ------------------------

// Mean and standard error of the mean of a list of values.
struct MeanSe {
  double mean = 0, se = 0;
  size_t n = 0;
};
MeanSe meanSe(const std::vector<double>& v);

// The mean over `replicates` independent renders (seeds 1..replicates) of a
// per-render statistic, with its standard error from their spread. For
// estimators that share randomness across an image (the per-layer shifts of
// vo's radii and ssat's sets), pixels are not independent draws; renders
// with different seeds are.
MeanSe replicateMean(int replicates, const std::function<double(uint32_t seed)>& stat);

// Every fully covered pixel of the pass (W = R / A), but a `border` of
// pixels along the image's edges, where part of a neighbourhood projects off
// the image (and reads as empty: nothing is known there).
std::vector<double> coveredW(const Film& f, int border = 0);

// Floor z = 0 (x >= 0) meeting a wall x = 0, seen from the open quadrant:
// every occluder of a floor point near the wall is the wall, which the depth
// buffer holds, and everything behind it is solid - the closed forms' world.
struct Crease {
  Scene scene;
  Camera cam;
  Crease();
  // The floor point seen through film position (fx, fy) of a w x h image, if any.
  bool floorAtFilm(int w, int h, float fx, float fy, Vec3& p) const;
  // The floor point seen through the centre of pixel (x, y), if any.
  bool floorAt(int w, int h, int x, int y, Vec3& p) const {
    return floorAtFilm(w, h, float(x) + 0.5f, float(y) + 0.5f, p);
  }
};

// VO with the normal at a floor point at distance h from the wall: the half
// ball above the floor minus the part behind the wall, which is half of the
// spherical cap of height R - h:
//   V = 1 - [pi (R-h)^2 (2R+h) / 3] / 2 / (2 pi R^3 / 3) = (2 + 3 eta - eta^3) / 4,
// eta = min(h / R, 1).
double creaseVo(double h, double R);

// The cosine-weighted visibility within R (`ao distance=R`, and `gtao`'s
// horizon estimator, which is exact here) at a floor point at distance h
// from the wall: the wall occludes the directions that meet it within R,
// -w_x > h / R, whose cosine-weighted share is the projected disk's segment
// beyond eta = min(h / R, 1) over pi:
//   v = 1 - (acos eta - eta sqrt(1 - eta^2)) / pi,   |dv/dh| <= 2 / (pi R).
double creaseCosine(double h, double R);

// The crease's floor pixels near the wall (h < 1.5 R, |y| < 1) whose right
// and lower neighbours see the floor too, V = closedForm(h, R) at each
// centre (default creaseVo), and the mean over them of the pixel-footprint
// bound: a pixel averages V over its area, where h varies by up to |dh/dx|
// + |dh/dy| between pixel centres, and |dV/dh| <= slope / R (creaseVo: 3/4;
// creaseCosine: 2/pi), so a pixel may differ from V at its centre by
// slope / R (|dh/dx| + |dh/dy|) / 2.
struct CreaseCentres {
  std::vector<std::pair<int, int>> pixels;
  std::vector<double> V;
  double footprint = 0.0;
};
CreaseCentres creaseCentres(const Crease& c, int w, int h, double R, double (*closedForm)(double, double) = creaseVo,
                            double slope = 0.75);

// --- files ------------------------------------------------------------------

// The whole file (empty if it cannot be read).
std::vector<unsigned char> readBytes(const std::string& path);
// Creates or replaces the file; a failed write is a test failure.
void writeBytes(const std::string& path, const void* data, size_t n);
void writeText(const std::string& path, const std::string& text);

// An image read back with OpenImageIO: the header, and every channel as a
// float plane looked up by name (OpenEXR stores channels sorted by name and
// OIIO may reorder them: docs/testing.md "Reading EXRs in tests"). Failing to
// open or read the file is a test failure; `ok` says both worked.
struct ReadBack {
  bool ok = false;
  OIIO::ImageSpec spec;
  std::map<std::string, std::vector<float>> planes;  // by channel name
};
ReadBack readExr(const std::string& path);

// Writes a one-channel float EXR of w x h texels holding f(u, v) at the
// texel centres in HeightMap's convention (u = (x + 0.5) / w, v = 0 at the
// bottom row); returns `path`.
std::string writeHeightMap(const std::string& path, int w, int h, const std::function<double(double u, double v)>& f);
// Writes a 16-bit RGB PNG of w x h texels holding f(u, v) (clamped to
// [0, 1]) at the texel centres, in writeHeightMap's convention; returns `path`.
std::string writeRgbTexture(const std::string& path, int w, int h, const std::function<Vec3(double u, double v)>& f);
// Appends a material whose albedo is the texture in the file at `path`
// (linear values, not sRGB); returns its index.
int addTexturedMaterial(Scene& scene, const std::string& path);
// Writes an 8-bit RGBA PNG of w x h texels whose alpha at texel (x, y) (row
// 0 at the top of the image) is alpha(x, y) in [0, 1], colour white.
std::string writeAlphaTexture(const std::string& path, int w, int h, const std::function<double(int x, int y)>& alpha);
// dir/ripples.exr: h(u, v) = 0.5 + 0.5 cos(4 pi u), 64 x 4 texels.
std::string writeRipples(const std::string& dir);

// --- warnings -----------------------------------------------------------------

// Collects (and so silences) warnings for the lifetime of the object.
struct WarningCapture {
  std::vector<std::string> messages;
  WarningCapture();
  ~WarningCapture();
  WarningCapture(const WarningCapture&) = delete;
  WarningCapture& operator=(const WarningCapture&) = delete;
  // How many messages contain `needle`.
  size_t count(const std::string& needle) const;
  // Every message, one a line, for failure output.
  std::string all() const;
};

// --- the CLI ------------------------------------------------------------------

struct CliResult {
  int exitCode = -1;  // -1 if killed by a signal or never started
  int signal = 0;
  std::string stderrText;
};

// Runs the obscura binary with `args`, stdout to /dev/null and stderr to
// the file stderrPath, and waits for it.
CliResult runCli(const std::vector<std::string>& args, const std::string& stderrPath);

// The two halves of runCli, for a test that signals the running process:
// startCli returns its pid (-1 with the reason in r.stderrText), finishCli
// waits for it and fills in r.
pid_t startCli(const std::vector<std::string>& args, const std::string& stderrPath, CliResult& r);
void finishCli(pid_t pid, const std::string& stderrPath, CliResult& r);

// Runs one process per argument list, a few at a time (each start costs
// ~0.4 s); the i-th one's stderr goes to dir/stderr<i>.txt.
std::vector<CliResult> runClis(const std::vector<std::vector<std::string>>& argLists, const std::string& dir);

}  // namespace obscura::test
