// The screen-space passes' guard band (docs/screen_space.md "Guard band";
// core/render/gbuffer.h layerGeometry): the G-buffer reaches beyond the
// frame, so a wall just off the image's edge occludes the edge's pixels as
// the traced twin says; without the band (guard-band=0) they read no
// occluder, as before the band existed. A region of a screen-space render
// is the same pixels of the full render, bit for bit.
#include <gtest/gtest.h>

#include <cstring>

#include <obscura/error.h>

#include "core/render/gbuffer.h"
#include "core/render/render.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// A floor (y = 0) seen from 3 up, looking down at 45 degrees towards +x,
// and a wall x = xw facing the camera, rising 1 above the floor, just
// beyond the floor point the image's top edge sees: every pixel sees the
// floor, the wall lies above the image, seen face on. The floor's points in
// the top rows are within R = 1 of the wall.
struct WallOffScreen {
  static constexpr int kW = 48, kH = 32;
  static constexpr float kFov = 0.8f;
  Scene scene;
  Camera cam = makeLookAtCamera(Vec3(0, 3, 0), Vec3(3, 0, 0), Vec3(0, 1, 0), kFov, "oblique");
  float xw = 0.0f;
  WallOffScreen() {
    // The top edge's ray dips 45 degrees - fov/2 below the horizon.
    xw = 3.0f / std::tan(0.25f * 3.14159265f - 0.5f * kFov) + 0.05f;
    const float h = 100.0f;
    // uv = (x, z): texture coordinates for ssat map= (the other passes ignore them).
    scene.addWorldPrimitive({{-h, 0, -h}, {-h, 0, h}, {h, 0, h}, {h, 0, -h}}, {0, 1, 2, 0, 2, 3}, {},
                            {-h, -h, -h, h, h, h, h, -h}, -1);
    scene.addWorldPrimitive({{xw, 0, -h}, {xw, 1, -h}, {xw, 1, h}, {xw, 0, h}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
    scene.commit();
  }
};

// Mean of R over the top `rows` rows of the image.
double edgeMean(const Film& f, int rows) {
  double sum = 0.0;
  int n = 0;
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < f.width(); ++x) sum += f.at(kR, x, y), ++n;
  return sum / n;
}

const std::vector<std::pair<std::string, std::vector<std::string>>>& edgePasses() {
  static const std::vector<std::pair<std::string, std::vector<std::string>>> passes = {
      {"vo", {"samples=line", "radius=1"}},
      {"vo", {"samples=point", "radius=1"}},
      {"ssat", {"distance=1", "silhouette=false", "interleave=off"}},
      {"gtao", {"radius=1", "interleave=off"}},
  };
  return passes;
}

// The band makes a pixel at the image's edge read what the same pixel reads
// inside a larger frame: the same camera with the film extended by k = 16
// pixels on every side (the field of view widened to keep every pixel's
// ray), where the wall is in the picture. The top rows of the frame and the
// same rows of the larger one (their own random numbers): the mean over 16
// independent renders of the difference within 4 standard errors. The
// z-buffer's own error beside the wall's foot (a pixel holds one surface's
// plane) is the same in both, so it cancels; against the traced twin it
// does not (measured below). Without the band the edge row reads exactly 1
// (nothing known beyond the image, and the floor is open).
TEST(GuardBand, AWallOffTheImageOccludesTheEdge) {
  const WallOffScreen s;
  const int W = WallOffScreen::kW, H = WallOffScreen::kH, k = 16;
  const float tallFov = 2.0f * std::atan(std::tan(0.5f * WallOffScreen::kFov) * float(H + 2 * k) / float(H));
  const Camera tall = makeLookAtCamera(Vec3(0, 3, 0), Vec3(3, 0, 0), Vec3(0, 1, 0), tallFov, "oblique, larger film");
  for (const auto& [integ, params] : edgePasses()) {
    for (int rows : {1, 2}) {
      const MeanSe d = replicateMean(16, [&](uint32_t seed) {
        const Film edge = renderWith(s.scene, s.cam, integ, params, passSettings(W, H, 4, seed));
        RenderSettings inside = passSettings(W + 2 * k, H + 2 * k, 4, seed + 1000);
        inside.region = {k, k, k + W, k + H};
        const Film f = renderWith(s.scene, tall, integ, params, inside);
        double sum = 0.0;
        for (int y = 0; y < rows; ++y)
          for (int x = 0; x < W; ++x) sum += f.at(kR, x + k, y + k);
        return edgeMean(edge, rows) - sum / (rows * W);
      });
      EXPECT_NEAR(d.mean, 0.0, 4 * d.se) << integ << " " << params[0] << " rows " << rows;
      RecordProperty(integ + "_" + params[0] + "_edge" + std::to_string(rows) + "_minus_inside", std::to_string(d.mean));
    }
    // The traced twin sees the wall: the edge is well below 1.
    const RenderSettings st = passSettings(W, H, 4);
    std::vector<std::string> traced = params;
    traced.push_back("depth=traced");
    EXPECT_LT(edgeMean(renderWith(s.scene, s.cam, integ, traced, st), 1), 0.9) << integ;
    std::vector<std::string> off = params;
    off.push_back("guard-band=0");
    const Film f = renderWith(s.scene, s.cam, integ, off, st);
    for (int x = 0; x < f.width(); ++x) EXPECT_EQ(f.at(kR, x, 0), 1.0f) << integ << " column " << x;
  }
}

// The automatic band: R projected from the scene's nearest point (the
// bounds' top, y = 1, 2 below the camera), at the view's corner: depth 2
// cos(half diagonal); capped at 1/8 of the larger side (min 16); the
// layer's origin a multiple of 4.
TEST(GuardBand, AutomaticBandIsRsProjectionCapped) {
  const WallOffScreen s;
  const auto geometry = [&](const std::vector<std::string>& params) {
    const auto p = makeIntegrator("vo", params);
    return layerGeometry(*p->screenSpace(), s.scene, s.cam, WallOffScreen::kW, WallOffScreen::kH,
                         PixelRect{0, 0, WallOffScreen::kW, WallOffScreen::kH});
  };
  const double tanHalf = std::tan(0.5 * WallOffScreen::kFov), aspect = double(WallOffScreen::kW) / WallOffScreen::kH;
  const double cosDiag = 1.0 / std::sqrt(1.0 + tanHalf * tanHalf * (1.0 + aspect * aspect));
  const double filmScale = 0.5 * WallOffScreen::kH / tanHalf;
  const double R = 0.2;
  const LayerGeometry g = geometry({"radius=0.2"});
  EXPECT_EQ(g.band, int(std::ceil(R * filmScale / (2.0 * cosDiag))) + 1);
  EXPECT_EQ(geometry({"radius=50"}).band, 16);  // the cap
  EXPECT_EQ(geometry({"radius=0.2", "guard-band=7"}).band, 7);
  EXPECT_EQ(geometry({"radius=0"}).band, 0);  // nothing read around the pixel
  EXPECT_EQ(g.originX % 4, 0);
  EXPECT_LE(g.originX, -g.band);
  EXPECT_GE(g.width + g.originX, WallOffScreen::kW + g.band);
  EXPECT_EQ(g.shaded.x0, -g.originX);
  EXPECT_EQ(g.shaded.width(), WallOffScreen::kW);
}

bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// A small crease (a 1 x 1 floor square and a wall square on its far edge)
// in the middle of the frame, nothing else: the background all round.
struct SmallCrease {
  static constexpr int kW = 128, kH = 96;  // the crease ~33 pixels a unit: reads reach past the 16-pixel cap
  Scene scene;
  Camera cam = makeLookAtCamera(Vec3(0, 2.2f, 2.2f), Vec3(0, 0.3f, 0), Vec3(0, 1, 0), 0.9f, "small");
  SmallCrease() {
    scene.addWorldPrimitive({{-0.5f, 0, -0.5f}, {-0.5f, 0, 0.5f}, {0.5f, 0, 0.5f}, {0.5f, 0, -0.5f}},
                            {0, 1, 2, 0, 2, 3}, {}, {}, -1);
    scene.addWorldPrimitive({{-0.5f, 0, -0.5f}, {0.5f, 0, -0.5f}, {0.5f, 1, -0.5f}, {-0.5f, 1, -0.5f}},
                            {0, 1, 2, 0, 2, 3}, {}, {}, -1);
    scene.commit();
  }
};

// When R projects wider than the automatic band's cap, reads are not
// limited to the band about each pixel but go anywhere within the band of
// the image (layerGeometry's readsImage). With the whole scene inside the
// frame, what lies beyond the image is background either way, so the pass
// must equal the one without a band (which reads the whole image) bit for
// bit; the same band given explicitly (reads within it of each pixel)
// calls open the wall pixels farther away and differs. Regions still equal
// the full render bit for bit.
TEST(GuardBand, ACappedBandReadsTheWholeImage) {
  const SmallCrease s;
  const int W = SmallCrease::kW, H = SmallCrease::kH;
  const std::vector<std::vector<std::string>> passes = {
      {"radius=3"}, {"radius=3", "samples=point"}, {"radius=3", "interleave=on"}};
  for (const auto& params : passes) {
    const auto p = makeIntegrator("vo", params);
    const LayerGeometry g = layerGeometry(*p->screenSpace(), s.scene, s.cam, W, H, PixelRect{0, 0, W, H});
    ASSERT_TRUE(g.readsImage) << "R = 3 should project wider than the cap";
    ASSERT_EQ(g.band, guardBandCap(W, H));
    const RenderSettings st = passSettings(W, H, 2, 3);
    const Film capped = renderWith(s.scene, s.cam, "vo", params, st);
    std::vector<std::string> none = params, fixed = params;
    none.push_back("guard-band=0");
    fixed.push_back("guard-band=" + std::to_string(g.band));
    const Film open = renderWith(s.scene, s.cam, "vo", none, st);
    const Film limited = renderWith(s.scene, s.cam, "vo", fixed, st);
    size_t differ = 0, differLimited = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        differ += !sameBits(capped.at(kR, x, y), open.at(kR, x, y));
        differLimited += !sameBits(limited.at(kR, x, y), open.at(kR, x, y));
      }
    EXPECT_EQ(differ, 0u) << params.back();
    EXPECT_GT(differLimited, 0u) << params.back();
    const int tiles[2][4] = {{0, 0, 19, 13}, {19, 13, W, H}};
    for (const auto& t : tiles) {
      RenderSettings rs = st;
      rs.region = {t[0], t[1], t[2], t[3]};
      const Film r = renderWith(s.scene, s.cam, "vo", params, rs);
      size_t d = 0;
      for (int y = t[1]; y < t[3]; ++y)
        for (int x = t[0]; x < t[2]; ++x) d += !sameBits(r.at(kR, x, y), capped.at(kR, x, y));
      EXPECT_EQ(d, 0u) << params.back() << " region " << t[0] << "," << t[1];
    }
  }
}

// Four regions of uneven sizes covering the frame (none aligned to 4 or to
// the 64-pixel tiles): each equals the full render's pixels, every channel,
// bit for bit - points, lines, areas (depth moments), interleaving with its
// filter, the blur (alone and after the filter), ssat with albedo, with the
// occluders' radiance (whose occluder estimates read within the shaded
// pixel's window) and with a height field (map=, a camera ray per pixel
// traced again for its uv), the traced twin.
TEST(GuardBand, RegionsEqualTheFullRenderBitForBit) {
  const WallOffScreen s;
  const int W = WallOffScreen::kW, H = WallOffScreen::kH;
  const int tiles[4][4] = {{0, 0, 13, 9}, {13, 0, W, 9}, {0, 9, 21, H}, {21, 9, W, H}};
  const std::string ripples = writeRipples(tempDir("guard_band_regions"));
  const std::vector<std::pair<std::string, std::vector<std::string>>> passes = {
      {"vo", {"samples=line", "radius=1"}},
      {"vo", {"samples=point", "radius=1", "interleave=on"}},
      {"vo", {"samples=area", "radius=1"}},
      {"vo", {"samples=area", "radius=1", "prefilter=off"}},
      {"vo", {"samples=area", "radius=0.5", "interleave=on", "guard-band=6"}},
      {"vo", {"samples=line", "radius=0.7", "depth=traced", "interleave=on"}},
      {"vo", {"samples=line", "radius=1", "blur=3"}},
      {"vo", {"samples=point", "radius=1", "interleave=on", "blur=2"}},
      {"ssat", {"distance=1"}},
      {"ssat", {"distance=1", "albedo=true", "steps=2", "guard-band=5"}},
      {"ssat", {"distance=1", "albedo=true", "occluder=radiance", "guard-band=5"}},
      {"ssat", {"distance=0.7", "albedo=true", "occluder=radiance", "depth=traced", "interleave=off"}},
      {"ssat", {"distance=1", "albedo=true", "map=" + ripples, "scale=0.1"}},
      {"ssat", {"distance=0.7", "map=" + ripples, "depth=traced", "interleave=off"}},
      {"gtao", {"radius=1"}},
      {"gtao", {"radius=0.5", "depth=traced", "e0=normal"}},
  };
  const WarningCapture warnings;  // ssat map=: the wall has no texture coordinates
  for (const auto& [integ, params] : passes) {
    RenderSettings st = passSettings(W, H, 3, 7);
    st.aovs = true;
    const Film full = renderWith(s.scene, s.cam, integ, params, st);
    for (const auto& t : tiles) {
      RenderSettings rs = st;
      rs.region = {t[0], t[1], t[2], t[3]};
      const Film r = renderWith(s.scene, s.cam, integ, params, rs);
      ASSERT_EQ(r.channels(), full.channels());
      size_t differ = 0;
      for (int c : full.channels())
        for (int y = t[1]; y < t[3]; ++y)
          for (int x = t[0]; x < t[2]; ++x) differ += !sameBits(r.at(c, x, y), full.at(c, x, y));
      EXPECT_EQ(differ, 0u) << integ << " " << params[0] << " " << params.back() << " region " << t[0] << "," << t[1];
    }
  }
  // Without a band a region is refused, in one line naming --region.
  RenderSettings rs = passSettings(W, H, 1);
  rs.region = {0, 0, 8, 8};
  try {
    renderWith(s.scene, s.cam, "vo", {"guard-band=0"}, rs);
    ADD_FAILURE() << "a region without a guard band rendered";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--region"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace obscura::test
