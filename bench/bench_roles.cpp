// obscura_bench_roles: what objects' roles and alpha cut-outs cost
// (docs/production.md "Objects and roles", "Speed").
//
// A foliage-like scene: a ground square and N leaf cards (quads of random
// position, orientation and size over it) in G groups, each group one world
// primitive and one object, all with uvs. The same geometry is rendered
// with `ao` (rays=2, R = inf) in one process, configurations interleaved run
// by run (the machine is shared and noisy; medians):
//   opaque     the cards without alpha: today's path (no filter runs)
//   mask       the cards as MASK cut-outs of a leaf-shaped alpha texture
//              (about half of each card open): a filter function per hit
//              on a card
//   blend      the cards BLEND with alpha 0.5 (no texture): a hashed coin per hit
//   filtered   BLEND with alpha 1 - 2^-20: the filter runs on every card hit
//              but (nearly) every hit stands, so rays do the opaque scene's
//              traversal: the filter's own cost, apart from the longer paths
//              of rays through cut-outs
//   masks      roles that only set masks: the ground hidden from the
//              camera, half the card groups not occluding
//   scoped     every card group occlusion=others: the context filter runs
//              for every candidate hit of every ray
// Mrays/s counts camera + occlusion rays; "vs opaque" is the ratio of
// median times measured in the same run. Masks change which rays hit what,
// so their time is not the same work: the row says what a user pays.
//
// Run:   build/bench/obscura_bench_roles                     960x540, 8 spp, 5 runs, 5000 cards
//        build/bench/obscura_bench_roles --quick             smoke run (320x180, 2 spp, 1 run)
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <random>

#include <OpenImageIO/imageio.h>

#include "bench/common.h"
#include <obscura/error.h>
#include "core/image/texture.h"

using namespace obscura;
using namespace obscura::bench;

namespace {

constexpr int kGroups = 16;

// A leaf: an ellipse with a serrated edge, alpha 1 inside, as 8-bit PNG
// bytes (decoded by the scene like a glTF texture).
std::vector<unsigned char> leafTexturePng(int n) {
  std::vector<unsigned char> px(size_t(n) * size_t(n) * 4, 255);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const double u = (x + 0.5) / n * 2 - 1, v = (y + 0.5) / n * 2 - 1;
      const double r = std::sqrt(u * u / 0.45 + v * v);
      const double edge = 0.95 + 0.05 * std::cos(16 * std::atan2(v, u));
      px[(size_t(y) * size_t(n) + size_t(x)) * 4 + 3] = r < edge ? 255 : 0;
    }
  const std::string path = (std::filesystem::temp_directory_path() / "obscura_bench_leaf.png").string();
  auto out = OIIO::ImageOutput::create(path);
  if (!out || !out->open(path, OIIO::ImageSpec(n, n, 4, OIIO::TypeDesc::UINT8)) ||
      !out->write_image(OIIO::TypeDesc::UINT8, px.data()))
    throw Error("cannot write " + path);
  out->close();
  std::FILE* f = std::fopen(path.c_str(), "rb");
  std::vector<unsigned char> bytes;
  for (int c; (c = std::fgetc(f)) != EOF;) bytes.push_back(static_cast<unsigned char>(c));
  std::fclose(f);
  std::filesystem::remove(path);
  return bytes;
}

enum class Cards { Opaque, Mask, Blend, Filtered };

// The scene: ground (object 0) and kGroups card groups (objects 1..G).
std::unique_ptr<Scene> foliage(int cards, Cards mode, const std::function<void(Scene&)>& roles,
                               const std::vector<unsigned char>& leaf) {
  auto scene = std::make_unique<Scene>();
  Material m;
  m.name = "leaf";
  if (mode == Cards::Mask) {
    scene->textures.push_back(std::make_unique<Texture>(leaf, "leaf.png", true));
    m.texture = 0;
    m.alphaMode = AlphaMode::Mask;
  } else if (mode == Cards::Blend || mode == Cards::Filtered) {
    m.alphaMode = AlphaMode::Blend;
    m.alpha = mode == Cards::Blend ? 0.5f : 1.0f - 0x1p-20f;
  }
  scene->materials.push_back(m);
  scene->objects.push_back({"ground", {}});
  for (int g = 0; g < kGroups; ++g) scene->objects.push_back({"cards_" + std::to_string(g), {}});
  scene->setCurrentObject(0);
  scene->addWorldPrimitive({{-12, -12, 0}, {12, -12, 0}, {12, 12, 0}, {-12, 12, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (int g = 0; g < kGroups; ++g) {
    std::vector<Vec3> p;
    std::vector<float> uv;
    std::vector<uint32_t> idx;
    for (int c = g; c < cards; c += kGroups) {
      const Vec3 centre(20 * U(rng) - 10, 20 * U(rng) - 10, 0.2f + 5 * U(rng));
      // A random orientation: two orthonormal edge directions.
      const Vec3 n = normalize(Vec3(2 * U(rng) - 1, 2 * U(rng) - 1, 2 * U(rng) - 1) + Vec3(0, 0, 1e-3f));
      const Frame f = Frame::fromNormal(n);
      const float s = 0.2f + 0.4f * U(rng);
      const Vec3 a = f.toWorld(Vec3(s, 0, 0)), b = f.toWorld(Vec3(0, s, 0));
      const uint32_t base = uint32_t(p.size());
      p.insert(p.end(), {centre - a - b, centre + a - b, centre + a + b, centre - a + b});
      uv.insert(uv.end(), {0, 1, 1, 1, 1, 0, 0, 0});
      idx.insert(idx.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    }
    scene->setCurrentObject(uint32_t(g + 1));
    scene->addWorldPrimitive(p, idx, {}, uv, 0);
  }
  scene->setCurrentObject(kNoObject);
  if (roles) roles(*scene);
  scene->commit();
  return scene;
}

struct Config {
  const char* name;
  Cards cards;
  std::function<void(Scene&)> roles;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"What objects' roles and alpha cut-outs cost"};
  CommonOptions common;
  common.res = "960x540";
  common.spp = 8;
  common.runs = 5;
  addCommonOptions(app, common, "smoke run: 320x180, 2 spp, 1 run");
  int cards = 5000;
  app.add_option("--cards", cards, "Leaf cards");
  CLI11_PARSE(app, argc, argv);
  try {
    if (common.quick) common.res = "320x180", common.spp = 2, common.runs = 1;
    if (common.scenes.empty()) common.scenes = {"unused"};
    if (cards < 1) throw Error("--cards: must be at least 1");
    const BenchSize size = checkCommonOptions(common);
    const ThreadLimit threads(common.threads);
    printMachine(threads.threads());
    const std::vector<unsigned char> leaf = leafTexturePng(64);
    const std::vector<Config> configs = {
        {"opaque", Cards::Opaque, {}},
        {"mask", Cards::Mask, {}},
        {"blend", Cards::Blend, {}},
        {"filtered", Cards::Filtered, {}},
        {"masks", Cards::Opaque,
         [](Scene& s) {
           s.objects[0].roles.camera = false;
           for (int g = 1; g <= kGroups; g += 2) s.objects[size_t(g)].roles.occluder = false;
         }},
        {"scoped", Cards::Opaque,
         [](Scene& s) {
           for (int g = 1; g <= kGroups; ++g) s.objects[size_t(g)].roles.occlusion = OcclusionScope::Others;
         }},
    };
    std::vector<std::unique_ptr<Scene>> scenes;
    for (const Config& c : configs) scenes.push_back(foliage(cards, c.cards, c.roles, leaf));
    const Camera camera = makeLookAtCamera(Vec3(0, -16, 9), Vec3(0, 0, 1.5f), Vec3(0, 0, 1), 0.8f, "bench");
    std::printf("foliage: ground + %d cards (%d triangles) in %d objects\n%dx%d, %d spp, ao rays=2, %d runs (medians)\n\n",
                cards, 2 * cards + 2, kGroups + 1, size.width, size.height, common.spp, common.runs);
    const BenchIntegrator ao("ao", {{"rays", "2"}});
    const RenderSettings s = benchRenderSettings(size.width, size.height, common.spp, threads.threads());
    std::vector<std::vector<double>> seconds(configs.size());
    std::vector<double> rays(configs.size(), 0), coverage(configs.size(), 0), mean(configs.size(), 0);
    for (int run = 0; run < common.runs; ++run)
      for (size_t i = 0; i < configs.size(); ++i) {
        RenderStats st;
        const Film f = ao.render(*scenes[i], camera, s, st);
        seconds[i].push_back(st.seconds);
        rays[i] = double(st.rays.camera + st.rays.occlusion);
        double a = 0, r = 0;
        for (int y = 0; y < size.height; ++y)
          for (int x = 0; x < size.width; ++x) a += f.at(kA, x, y), r += f.at(kR, x, y);
        coverage[i] = a / (double(size.width) * size.height);
        mean[i] = a > 0 ? r / a : 0;
      }
    std::printf("%-8s %9s %9s %10s %9s %9s %11s\n", "config", "alpha", "render s", "Mrays/s", "vs opaque", "coverage", "mean W");
    const double base = median(seconds[0]);
    for (size_t i = 0; i < configs.size(); ++i) {
      const double t = median(seconds[i]);
      std::printf("%-8s %9zu %9.3f %10.2f %9.3f %9.4f %11.4f\n", configs[i].name, scenes[i]->alphaPrimitives(), t,
                  rays[i] / t * 1e-6, t / base, coverage[i], mean[i]);
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "obscura_bench_roles: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
