// `multibounce` where the two AO flavours differ (docs/math.md §6, §7): the
// wall point opposite the hole of a spherical cavity (radius 1, hole of
// half-angle alpha = 60 degrees), seen from the centre through a 1e-4 lens.
// There a direction at angle theta from the normal escapes iff
// theta < alpha/2 (the chord to the hole's edge), so
//   uniform visibility   alpha_u = Int_0^(alpha/2) sin(theta) dtheta = 1 - cos(alpha/2) = 0.1340
//   cosine visibility    v = sin^2(alpha/2) = (1 - cos alpha)/2 = f = 0.25.
// `mapping=improved` must map alpha_u, `mapping=gtao` must map v, each with
// the pixel's albedo per channel (wall albedo (0.9, 0.5, 0.1)).
//
// Each pixel holds G(AO_pixel, rho_c), AO_pixel the mean of its n = spp x rays
// visibility samples. G is increasing in the AO value (test_multibounce.cpp),
// so inverting it per pixel recovers AO_pixel, whose mean over the
// (independent) pixels estimates the AO without the bias of a nonlinear map:
// compared with alpha_u (resp. v) within 4 standard errors of that mean plus
// D^2 for the tessellated hole's edge (test_ao_analytic.cpp). The image
// mean of G itself is compared with G(alpha_u, rho) too, within 4 standard
// errors of the image mean, the change of G over D^2 and twice the second-order (delta method) bias
// |G''| Var(AO_pixel) / 2 with the measured pixel variance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "integrators/multibounce_mapping.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr int kRings = 256, kSegments = 512;
const double kStep = std::max(2.0 * M_PI / kSegments, M_PI / kRings);
const double kTess = kStep * kStep;

// The smallest AO value x in [0, 1] with G(x, rho) >= W (bisection: G is
// non-decreasing in x).
template <class G>
double invert(G g, double W, double rho) {
  double lo = 0, hi = 1;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (g(mid, rho) >= W ? hi : lo) = mid;
  }
  return hi;
}

TEST(MultiBounceCavity, EachMappingGetsItsAoFlavour) {
  const double alpha = M_PI / 3, uniform = 1 - std::cos(alpha / 2), cosine = (1 - std::cos(alpha)) / 2;
  const Vec3 rho(0.9f, 0.5f, 0.1f);
  Scene scene;
  Material m;
  m.name = "wall";
  m.baseColorFactor = rho;
  scene.materials.push_back(m);
  addSphereCavity(scene, 1.0f, alpha, kRings, kSegments, 0);
  scene.setRobust(true);  // the 512-valent pole (test_ao_analytic.cpp)
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 1, 0), 1e-4f, "antipode");
  const int w = 16, h = 16, spp = 64, rays = 16;
  const struct {
    const char* mapping;
    double (*G)(double, double);
    double ao, other;  // the flavour it must see, the one it must not
  } cases[] = {{"mapping=improved", improvedMultiBounce, uniform, cosine},
               {"mapping=gtao", gtaoMultiBounce, cosine, uniform}};
  for (const auto& cs : cases) {
    const Film film = renderWith(scene, cam, "multibounce", {cs.mapping, "rays=" + std::to_string(rays)},
                                 passSettings(w, h, spp));
    for (int c = 0; c < 3; ++c) {
      // The AO each pixel's value was mapped from.
      std::vector<double> ao;
      double sumW = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          ASSERT_EQ(film.at(kA, x, y), 1.0f);
          const double W = film.at(kR + c, x, y);
          ao.push_back(invert(cs.G, W, rho[c]));
          sumW += W;
        }
      double mean = 0, var = 0;
      for (double a : ao) mean += a;
      mean /= double(ao.size());
      for (double a : ao) var += (a - mean) * (a - mean);
      var /= double(ao.size() - 1);
      const double se = std::sqrt(var / double(ao.size()));
      const double tol = 4 * se + kTess;
      std::printf("%s channel %d: AO from the pixels %.5f (expected %.5f, the other flavour %.5f) SE %.2g tol %.2g\n",
                  cs.mapping, c, mean, cs.ao, cs.other, se, tol);
      EXPECT_NEAR(mean, cs.ao, tol) << cs.mapping << " channel " << c;
      EXPECT_GT(std::abs(cs.other - cs.ao), 10 * tol) << "the flavours must differ here";
      // The image mean against the mapping of the exact AO.
      const double G0 = cs.G(cs.ao, rho[c]), dx = 1e-3;
      const double G1 = (cs.G(cs.ao + dx, rho[c]) - cs.G(cs.ao - dx, rho[c])) / (2 * dx);
      const double G2 = (cs.G(cs.ao + dx, rho[c]) - 2 * G0 + cs.G(cs.ao - dx, rho[c])) / (dx * dx);
      const double meanW = sumW / double(ao.size());
      const double tolW = 4 * pixelStats(film, kR + c).se + std::abs(G1) * kTess + std::abs(G2) * var;
      std::printf("  mean W %.5f expected G(ao) %.5f tol %.2g; G(other flavour) %.5f\n", meanW, G0, tolW,
                  cs.G(cs.other, rho[c]));
      EXPECT_NEAR(meanW, G0, tolW) << cs.mapping << " channel " << c;
      EXPECT_GT(std::abs(cs.G(cs.other, rho[c]) - G0), 10 * tolW) << cs.mapping << " channel " << c;
    }
  }
}

}  // namespace
}  // namespace obscura::test
