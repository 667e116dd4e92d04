// Ambient occlusion at the trough of a corrugated sheet - a flat cage
// subdivided and displaced by a sinusoidal height map (core/subd/subdivision.h) -
// against a numeric integral that never calls the renderer.
//
// The sheet: z(x) = A cos(2 pi x / L), extruded along y. For a surface
// invariant along y, a ray is blocked iff its projection onto the (x, z)
// cross-section is: the ray's y travel does not matter. Cosine-weighted
// directions about +z project to an angle alpha from the normal within the
// cross-section with density cos(alpha) / 2: the directions with projected
// angle below alpha lie on one side of the plane through the y axis tilted
// by alpha, whose hemisphere part projects onto the unit disk as the half
// disk plus half an ellipse of semi-axes sin(alpha) and 1, i.e. cosine
// measure (pi/2 + pi sin(alpha)/2) / pi = (1 + sin alpha) / 2. With the
// horizon elevations h_L, h_R on either side, the visible projected angles
// are (-(pi/2 - h_L), pi/2 - h_R), so
//
//   AO = [sin(pi/2 - h_R) + sin(pi/2 - h_L)] / 2 = (cos h_L + cos h_R) / 2,
//
// and the horizons are found numerically: the maximum of
// atan((z(x) - z(x0)) / |x - x0|) over the sheet's profile on a fine grid.
#include <gtest/gtest.h>

#include <cmath>

#include "core/subd/subdivision.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr double kWave = 1.0;               // L, the wavelength
constexpr double kAmp = kWave / M_PI;       // A: max slope 2 pi A / L = 2, a deep trough (h ~ 55 deg)
constexpr double kX0 = -1.0, kX1 = 2.0;     // the sheet's extent in x: three periods
constexpr double kTrough = 0.5;             // z(kTrough) = -A
constexpr double kDepth = 2000.0;           // the sheet's extent in y, centred on y = 0
constexpr int kCageX = 12, kCageY = 2;      // cage quads
constexpr int kLevel = 5;                   // 2^5 refined segments per cage edge
constexpr int kTexels = 1024;               // height map texels per wavelength

double profile(double x) { return kAmp * std::cos(2 * M_PI * x / kWave); }

// Largest elevation angle of the profile seen from x0 towards `side` (+1 or
// -1), over the sheet's extent, on a grid of step 1e-5 L (the maximum is
// smooth, so the grid loses O(step^2)).
double horizon(double x0, int side) {
  const double end = side > 0 ? kX1 : kX0, step = 1e-5 * kWave;
  double best = -M_PI / 2;
  for (double d = step; d <= std::abs(end - x0); d += step)
    best = std::max(best, std::atan2(profile(x0 + side * d) - profile(x0), d));
  return best;
}

double referenceAo(double x0) { return (std::cos(horizon(x0, -1)) + std::cos(horizon(x0, +1))) / 2; }

TEST(DisplacedTrough, AoMatchesTheHorizonIntegral) {
  const std::string dir = tempDir("displaced_trough");
  // h(u) = 0.5 + 0.5 cos(2 pi u), so scale 2A, midlevel 0.5 gives z = A cos(2 pi x / L) with u = x / L.
  const HeightMap hm(writeHeightMap(dir + "/wave.exr", kTexels, 2, [](double u, double) { return 0.5 + 0.5 * std::cos(2 * M_PI * u); }));
  SubdivisionCage cage;
  for (int j = 0; j <= kCageY; ++j)
    for (int i = 0; i <= kCageX; ++i) {
      const double x = kX0 + (kX1 - kX0) * i / kCageX, y = kDepth * (double(j) / kCageY - 0.5);
      cage.positions.emplace_back(float(x), float(y), 0.0f);
      cage.uvs.insert(cage.uvs.end(), {float(x / kWave), float(j) / kCageY});
    }
  for (int j = 0; j < kCageY; ++j)
    for (int i = 0; i < kCageX; ++i) {
      const int a = j * (kCageX + 1) + i;
      for (const int k : {a, a + 1, a + kCageX + 2, a + kCageX + 1}) cage.faceIndices.push_back(k), cage.uvIndices.push_back(k);
      cage.faceSizes.push_back(4);
    }
  SubdividedMesh m = subdivide(cage, SubdivisionScheme::CatmullClark, kLevel, size_t(1) << 30, "sheet");
  // The flat cage's limit is the cage with uv = (x / L, .), vertices on a
  // regular grid of step dx and limit normals exactly +z: the displaced
  // sheet is the piecewise-linear interpolant, in x, of the height map.
  const double dx = (kX1 - kX0) / kCageX / (1 << kLevel);
  bool troughVertex = false;
  for (size_t i = 0; i < m.positions.size(); ++i) {
    ASSERT_NEAR(m.uvs[2 * i], m.positions[i].x / kWave, 1e-6);
    const double cells = (m.positions[i].x - kX0) / dx;
    ASSERT_NEAR(cells, std::round(cells), 1e-4);
    ASSERT_EQ(m.normals[i].z, 1.0f);
    troughVertex = troughVertex || (m.positions[i].x == float(kTrough) && std::abs(m.positions[i].y) < 1e-3f);
  }
  ASSERT_TRUE(troughVertex) << "the camera aims at a vertex on the trough line";
  displace(m, hm, 2 * kAmp, 0.5);
  Scene scene;
  scene.addWorldPrimitive(m.positions, m.triangles, m.normals, {}, -1);
  scene.setRobust(true);  // no ray slips between the sheet's triangles
  scene.commit();

  // A camera straight above the trough whose view spans +-r there: every
  // camera sample hits within r of the trough line (box pixel filter).
  const double r = 2e-4, height = 1.0;
  const float yfov = float(2 * std::atan(r / (height + kAmp)));
  const Camera cam = makeLookAtCamera(Vec3(float(kTrough), 0, float(height)), Vec3(float(kTrough), 0, float(-kAmp)),
                                      Vec3(0, 1, 0), yfov, "above");
  const int w = 4, h = 4, spp = 256, rays = 64;
  size_t covered = 0;
  const Film film = renderWith(scene, cam, "ao", {"rays=" + std::to_string(rays)}, passSettings(w, h, spp));
  const double ao = meanCovered(film, kR, &covered);
  ASSERT_EQ(covered, size_t(w * h));

  const double ref = referenceAo(kTrough);
  const double hTrough = horizon(kTrough, +1);
  // Closed-form check of the numeric horizon: tan h = (2 pi A / L) max_t (1 - cos t) / t, max at t = 2.3311.
  EXPECT_NEAR(std::tan(hTrough), 2 * M_PI * kAmp / kWave * (1 - std::cos(2.331122370414423)) / 2.331122370414423, 1e-8);

  // Deterministic bounds.
  // (1) The surface is within delta of z(x): the chord error of the
  //     piecewise-linear interpolant dx^2 / 8 max|z''|, plus the height
  //     map's bilinear lookup error (1/texels)^2 / 8 max|h''| times the scale.
  const double z2 = kAmp * std::pow(2 * M_PI / kWave, 2);
  const double delta = dx * dx / 8 * z2 + 2 * kAmp * std::pow(1.0 / kTexels, 2) / 8 * 0.5 * std::pow(2 * M_PI, 2);
  //     That moves (z(x0 + d) - z(x0)) / d by at most 2 delta / d. The
  //     maximum lies beyond d_lo = 0.1 L on either surface: below it the
  //     profile rises at most z'' d^2 / 2 (so the ratio is <= z'' d / 2) and
  //     the interpolant adds at most 2 delta / dx.
  const double dLo = 0.1 * kWave, tanH = std::tan(hTrough), dTan = 2 * delta / dLo;
  ASSERT_LT(z2 * dLo / 2 + 2 * delta / dx, tanH - dTan);
  //     dh <= dtan / (1 + tan_min^2), and |d cos h| <= sin(h_max) dh.
  const double dH = dTan / (1 + std::pow(tanH - dTan, 2));
  const double horizonBound = std::sin(hTrough + dH) * dH;
  // (2) Hits within r of the trough: AO there differs from AO at the trough
  //     by the reference's own change (second order by symmetry).
  const double footprintBound = std::max(std::abs(referenceAo(kTrough + r) - ref), std::abs(referenceAo(kTrough - r) - ref));
  // (3) The shading normal there tilts by at most the neighbouring vertex
  //     normal's tilt (<= max|z'| over 2 dx <= 2 z'' dx) times r / dx, doubled
  //     for normalization; a tilt e turns (cos h_L + cos h_R) / 2 into
  //     (cos(h_L - e) + cos(h_R + e)) / 2 = cos h cos e at the symmetric
  //     trough. (Directions the tilt puts below the geometric surface lie
  //     far below the horizon, occluded either way.)
  const double tilt = 2 * (2 * z2 * dx) * (r / dx);
  const double tiltBound = 1 - std::cos(tilt);
  // (4) The sheet ends at y = +-D/2: a ray occluded on the infinite sheet
  //     meets it within x travel d* = 0.371 L (the tangent point; 0.4 L
  //     allowed), so it escapes only if |w_y / w_x| > (D/2) / 0.4 L; w_x, w_y
  //     are uniform on the unit disk for cosine-weighted directions, so that
  //     has probability (2 / pi) atan(0.4 L / (D/2)).
  const double escapeBound = 2 / M_PI * std::atan(0.4 * kWave / (kDepth / 2));
  const double deterministic = horizonBound + footprintBound + tiltBound + escapeBound;
  const double se = bernoulliStdErr(ref, double(w * h) * spp * rays);
  std::printf("trough AO %.5f, reference %.5f (h = %.4f rad), |diff| %.5f, 4 SE %.5f + bounds %.6f "
              "(horizon %.2g, footprint %.2g, tilt %.2g, escape %.2g)\n",
              ao, ref, hTrough, std::abs(ao - ref), 4 * se, deterministic, horizonBound, footprintBound, tiltBound,
              escapeBound);
  EXPECT_NEAR(ao, ref, 4 * se + deterministic);
}

}  // namespace
}  // namespace obscura::test
