// Issue #37: memory nobody refused up front, and inputs that are not
// regular files (a FIFO blocks a read forever, /dev/zero never ends). Each hostile input is built here (a PNG header claiming
// 30000^2, a GLB declaring a 16384^2 texture, an edited display window,
// a FIFO, /dev/zero); each refusal is asserted as its one error line, and
// run under an address-space limit below the allocation it replaces, so a
// refusal that came after the allocation would fail as "out of memory"
// instead (docs/cli.md "Memory").
#include <gtest/gtest.h>

#include <OpenImageIO/imagebuf.h>
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <obscura/error.h>

#include "core/image/image_io.h"
#include "core/image/texture_size.h"
#include "core/util/memory_budget.h"
#include "core/util/option_names.h"
#include "tests/gltf_builder.h"
#include "tests/limited_cli.h"
#include "tests/png_crc.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr uint64_t kGiB = uint64_t(1) << 30;
// The limit the refused runs work under: room for the program (its
// libraries, thread stacks, a small scene) but not for any of the
// allocations refused below (2 GiB and more each).
constexpr uint64_t kAddressSpace = kGiB + kGiB / 2;

void chunk(std::vector<unsigned char>& png, const char* type, const std::vector<unsigned char>& data) {
  const auto be32 = [&](uint32_t v) {
    for (int s = 24; s >= 0; s -= 8) png.push_back((unsigned char)(v >> s));
  };
  be32(uint32_t(data.size()));
  const size_t at = png.size();
  png.insert(png.end(), type, type + 4);
  png.insert(png.end(), data.begin(), data.end());
  be32(bitwiseCrc32(png.data() + at, png.size() - at));
}

// A 65-byte PNG: an IHDR claiming w x h 8-bit grey pixels, an IDAT of an
// empty zlib stream, IEND. Readers size their buffers from the IHDR.
// `padding` bytes of an ancillary chunk after the IHDR make the file as
// large as a real one of that size could be.
std::vector<unsigned char> pngHeader(uint32_t w, uint32_t h, size_t padding = 0) {
  std::vector<unsigned char> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<unsigned char> ihdr;
  for (uint32_t v : {w, h})
    for (int s = 24; s >= 0; s -= 8) ihdr.push_back((unsigned char)(v >> s));
  ihdr.insert(ihdr.end(), {8, 0, 0, 0, 0});  // 8 bits, grey, deflate, no filter, not interlaced
  chunk(png, "IHDR", ihdr);
  if (padding > 0) chunk(png, "obPd", std::vector<unsigned char>(padding, 0));
  chunk(png, "IDAT", {0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01});
  chunk(png, "IEND", {});
  return png;
}

// A quad cage with a texture coordinate at every corner (for --displace).
std::string writeCage(const std::string& dir, const std::string& head = "") {
  const std::string path = dir + "/cage.obj";
  writeText(path, head + "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n");
  return path;
}

// One line on stderr, exit status 1, containing each of `parts`.
void expectRefusal(const CliResult& r, const std::vector<std::string>& parts) {
  EXPECT_EQ(r.exitCode, 1) << r.stderrText;
  EXPECT_EQ(r.signal, 0) << r.stderrText;
  EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  EXPECT_EQ(r.stderrText.find("out of memory"), std::string::npos) << r.stderrText;
  for (const std::string& p : parts) EXPECT_NE(r.stderrText.find(p), std::string::npos) << p << "\n" << r.stderrText;
}

// DIR/texture.glb: a textured quad and a camera, its base-colour texture a
// PNG header claiming `size`^2 texels (65 bytes: decoding it would fail, so
// a refusal must come from the estimate, before).
std::string textureGlb(const std::string& dir, uint32_t size) {
  GltfBuilder g;
  const std::vector<unsigned char> png = pngHeader(size, size);
  g.push("images", {{"bufferView", g.bufferView(png.data(), png.size())}, {"mimeType", "image/png"}});
  g.push("textures", {{"source", 0}});
  g.push("materials", {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}});
  g.node({{"mesh", g.quadMesh(1, 0, true)}});
  g.push("cameras", perspective("", 0.8, 0.01));
  g.node({{"camera", 0}, {"translation", {0, 0, 3}}});
  g.scene({0, 1});
  const std::string glb = g.writeGlb(dir, "texture");
  return glb;
}

TEST(MemoryBudget, TextureSizeComesFromTheHeaderAlone) {
  // decode() keeps one word per texel of an 8-bit image and stb's RGBA
  // buffer (4 bytes a texel) while it runs.
  const DecodedImageSize d = decodedImageSize(pngHeader(16384, 16384));
  EXPECT_EQ(d.width, 16384);
  EXPECT_EQ(d.height, 16384);
  EXPECT_EQ(d.kept, uint64_t(16384) * 16384 * 4);
  EXPECT_EQ(d.transient, uint64_t(16384) * 16384 * 4);
  EXPECT_EQ(decodedImageSize({1, 2, 3}).kept, 0u);  // no header: decode() reports it
}

TEST(MemoryBudget, RefusesAGlbDeclaringAHugeTextureBeforeDecoding) {
  const std::string dir = tempDir("budget_texture");
  const std::string glb = textureGlb(dir, 16384);
  // 16384^2 texels at 4 bytes kept and 4 decoding: 2.0 GiB, over 1 GiB.
  const LimitedCliResult r = runCliLimited(
      {"render", glb, "-o", dir + "/out.exr", "--res", "8x8", "--spp", "1", "-q", "--max-memory", "1"}, dir + "/err.txt",
      kAddressSpace);
  expectRefusal(r, {glb + ": needs an estimated ", "textures 2.0 GiB", "over the --max-memory budget of 1.0 GiB"});
  EXPECT_FALSE(std::filesystem::exists(dir + "/out.exr"));
}

TEST(MemoryBudget, RefusesAHeightMapOf30000SquaredOverTheBudgetBeforeReading) {
  const std::string dir = tempDir("budget_heightmap");
  // As large as deflate needs for 30000 x 30001 filtered bytes (1032:1),
  // so the size bound (the test below) passes it and the budget decides.
  const std::vector<unsigned char> png = pngHeader(30000, 30000, 30000ull * 30001ull / 1032 + 1);
  writeBytes(dir + "/big.png", png.data(), png.size());
  // 30000^2 float texels: 3.35 GiB.
  const LimitedCliResult r = runCliLimited(
      {"info", writeCage(dir), "--subdiv", "catmull-clark", "--displace", dir + "/big.png", "--max-memory", "1"},
      dir + "/err.txt", kAddressSpace);
  expectRefusal(r, {dir + "/big.png: the height map's 30000x30000 texels: needs 3.4 GiB, over the --max-memory budget of 1.0 GiB"});
}

// Whatever the budget: deflate packs at most 1032 bytes into one, so 65
// bytes cannot hold 30000 x 30001 filtered bytes (grey, a filter byte a row).
TEST(MemoryBudget, RefusesAPngHeaderItsFileCannotHoldAtAnyBudget) {
  const std::string dir = tempDir("budget_png_bound");
  const std::vector<unsigned char> png = pngHeader(30000, 30000), small = pngHeader(1, 1);
  ASSERT_EQ(png.size(), 65u);
  writeBytes(dir + "/big.png", png.data(), png.size());
  const LimitedCliResult r = runCliLimited(
      {"info", writeCage(dir), "--subdiv", "catmull-clark", "--displace", dir + "/big.png", "--max-memory", "100"},
      dir + "/err.txt", kAddressSpace);
  expectRefusal(r, {dir + "/big.png: the PNG header declares 30000x30000 pixels (" + std::to_string(30000ull * 30001ull) +
                    " bytes of image data), more than its 65 bytes can hold"});
  // 1 x 1 (2 filtered bytes) fits: that file fails later, in its reader.
  writeBytes(dir + "/small.png", small.data(), small.size());
  const CliResult ok = runCli({"info", writeCage(dir), "--subdiv", "catmull-clark", "--displace", dir + "/small.png"},
                              dir + "/small_err.txt");
  EXPECT_EQ(ok.stderrText.find("can hold"), std::string::npos) << ok.stderrText;
}

TEST(MemoryBudget, CompareRefusesItsFilmsBeforeLoadingTheScene) {
  const std::string dir = tempDir("budget_compare");
  const LimitedCliResult r =
      runCliLimited({"compare", sourcePath("scenes/default.gltf"), "-o", dir + "/cmp", "--res", "9000x9000", "-c", "ao",
                     "-q", "--max-memory", "1"},
                    dir + "/err.txt", kAddressSpace);
  expectRefusal(r, {"--res 9000x9000: the films: needs ", "over the --max-memory budget of 1.0 GiB"});
  EXPECT_FALSE(std::filesystem::exists(dir + "/cmp"));
}

// --max-memory bounds the whole process: what is held (a film) counts in
// every later check, and is released with its hold.
TEST(MemoryBudget, HeldMemoryCountsInLaterChecks) {
  const uint64_t before = memoryBudget();
  setMemoryBudget(kGiB);
  {
    const MemoryHold film(600ull << 20, "film");
    EXPECT_EQ(memoryHeld(), 600ull << 20);
    EXPECT_NO_THROW(requireMemory(424ull << 20, "scene"));  // 600 + 424 MiB = the budget
    try {
      requireMemory(425ull << 20, "scene");
      ADD_FAILURE() << "600 + 425 MiB passed a 1 GiB budget";
    } catch (const Error& e) {
      // The option's name as the front end spells it (core/util/option_names).
      EXPECT_EQ(std::string(e.what()), "scene: needs 425.0 MiB beside the 600.0 MiB this process already holds, over the " +
                                           settingName(Setting::MaxMemory) + " budget of 1.0 GiB");
    }
    EXPECT_THROW(MemoryHold(kGiB, "second film"), Error);  // a refused hold holds nothing
    EXPECT_EQ(memoryHeld(), 600ull << 20);
  }
  EXPECT_EQ(memoryHeld(), 0u);
  EXPECT_NO_THROW(requireMemory(kGiB, "scene"));
  setMemoryBudget(before);
}

// A render's film and its scene each fit the budget, together they do not:
// the scene is refused beside the film, before the texture is decoded.
TEST(MemoryBudget, RenderRefusesTheSceneBesideItsFilm) {
  const std::string dir = tempDir("budget_film_and_scene");
  const std::string glb = textureGlb(dir, 8192);  // 256 MiB kept, 256 MiB decoding
  // The film of 4500 x 4500 without AOVs: its size from the renderer's own
  // accounting (image_io.h), chosen so that film and textures straddle 0.75 GiB.
  const uint64_t film = filmBytes(4500, 4500, false), textures = 512ull << 20, budget = 3 * kGiB / 4;
  ASSERT_LT(film, budget);
  ASSERT_LT(textures, budget);
  ASSERT_GT(film + textures, budget);
  const LimitedCliResult r = runCliLimited({"render", glb, "-o", dir + "/out.exr", "--res", "4500x4500", "--spp", "1",
                                            "--no-aovs", "-q", "--max-memory", "0.75"},
                                           dir + "/err.txt", kAddressSpace);
  expectRefusal(r, {glb + ": needs an estimated ", "textures 512.0 MiB", " beside the " + formatBytes(film) +
                    " this process already holds, over the --max-memory budget of 768.0 MiB"});
  EXPECT_FALSE(std::filesystem::exists(dir + "/out.exr"));
}

TEST(MemoryBudget, MergeRefusesAnEditedDisplayWindowBeforeAllocating) {
  const std::string dir = tempDir("budget_merge");
  const CliResult tile = runCli({"render", "-q", "--res", "37x23", "--spp", "1", "--no-aovs", "--region", "0,0,37,23",
                                 "-o", dir + "/tile.exr"},
                                dir + "/render_err.txt");
  ASSERT_EQ(tile.exitCode, 0) << tile.stderrText;
  // The same tile with its display window edited to 60000^2.
  OIIO::ImageBuf buf(dir + "/tile.exr");
  ASSERT_TRUE(buf.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << buf.geterror();
  buf.specmod().full_width = buf.specmod().full_height = 60000;
  ASSERT_TRUE(buf.write(dir + "/edited.exr")) << buf.geterror();
  // The coverage map alone is 3.4 GiB, the frame 4 channels of 60000^2.
  const LimitedCliResult r =
      runCliLimited({"merge", dir + "/merged.exr", dir + "/edited.exr"}, dir + "/err.txt", kAddressSpace);
  expectRefusal(r, {dir + "/edited.exr: display window 60000x60000 at (0,0), 4 channels: needs ",
                    "over the --max-memory budget of 8.0 GiB"});
  EXPECT_FALSE(std::filesystem::exists(dir + "/merged.exr"));
}

TEST(MemoryBudget, InfoPrintsTheEstimate) {
  const std::string dir = tempDir("budget_info");
  const std::string out = dir + "/info.txt";
  const std::string cmd = std::string(obscuraBinary()) + " info " + sourcePath("scenes/default.gltf") + " > " + out;
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  const std::vector<unsigned char> bytes = readBytes(out);
  const std::string text(bytes.begin(), bytes.end());
  // The default film (960x540, every AOV) is part of it, and the default budget.
  EXPECT_NE(text.find("\nestimate   "), std::string::npos) << text;
  EXPECT_NE(text.find("film at --res"), std::string::npos) << text;
  EXPECT_NE(text.find(" of 8.0 GiB budget"), std::string::npos) << text;
}

// The cause of 3.8 GB for 400k leaves under 998 levels: every mesh use
// carried a copy of its ancestor list (4 bytes a level, in the document's
// uses and each pose's). Leaves deep down cost what leaves at the top cost.
TEST(MemoryBudget, DeepLeavesCostNoMoreThanShallowOnes) {
  const std::string dir = tempDir("budget_deep");
  constexpr int kLeaves = 40000, kDepth = 998;
  const auto write = [&](int depth, const std::string& name) {
    GltfBuilder g;
    const int mesh = g.quadMesh(0.01f);
    g.push("cameras", perspective("", 0.8, 0.01));
    std::vector<int> chain;
    for (int i = 0; i < depth; ++i) chain.push_back(g.node(json::object()));
    for (int i = 0; i + 1 < depth; ++i) g.doc["nodes"][size_t(chain[i])]["children"] = {chain[size_t(i) + 1]};
    json leaves = json::array();
    for (int j = 0; j < kLeaves; ++j) leaves.push_back(g.node({{"mesh", mesh}, {"translation", {0.001 * j, 0, 0}}}));
    g.doc["nodes"][size_t(chain.back())]["children"] = leaves;
    g.scene({chain.front(), g.node({{"camera", 0}, {"translation", {0, 0, 3}}})});
    return g.writeGltf(dir, name);
  };
  const LimitedCliResult deep = runCliLimited({"info", write(kDepth, "deep")}, dir + "/deep.txt", 0);
  const LimitedCliResult flat = runCliLimited({"info", write(1, "flat")}, dir + "/flat.txt", 0);
  ASSERT_EQ(deep.exitCode, 0) << deep.stderrText;
  ASSERT_EQ(flat.exitCode, 0) << flat.stderrText;
  // A list per leaf would add kDepth x 4 bytes x 2 copies = 8 KB a leaf
  // (320 MB); a kilobyte a leaf is far above the 997 extra nodes' cost and
  // far below the lists'.
  EXPECT_LT(double(deep.peakRssBytes), double(flat.peakRssBytes) + 1000.0 * kLeaves)
      << "deep " << deep.peakRssBytes << " flat " << flat.peakRssBytes;
}

// --- inputs that are not regular files -------------------------------------

TEST(InputFiles, FifosAndDevicesAreRefusedByName) {
  const std::string dir = tempDir("inputs_fifo");
  const std::string fifo = dir + "/scene.gltf";
  std::filesystem::remove(fifo);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const std::string scene = sourcePath("scenes/default.gltf");
  const std::string cageDir = dir + "/cage";
  std::filesystem::create_directories(cageDir);
  std::filesystem::remove(cageDir + "/lib.mtl");
  ASSERT_EQ(mkfifo((cageDir + "/lib.mtl").c_str(), 0600), 0);
  const std::string cage = writeCage(cageDir, "mtllib lib.mtl\n");
  const std::string checkpoint = dir + "/out.exr.checkpoint";
  std::filesystem::remove(checkpoint);
  ASSERT_EQ(mkfifo(checkpoint.c_str(), 0600), 0);
  const std::vector<std::string> render = {"render", scene, "-q", "--res", "8x8", "--spp", "1"};
  const auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = render;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::string chr = ": is a character device, not a regular file";
  const std::vector<Case> cases = {
      {{"info", fifo}, fifo + ": is a FIFO, not a regular file"},
      {{"info", cage, "--subdiv", "catmull-clark"}, "mtllib " + cageDir + "/lib.mtl: is a FIFO, not a regular file"},
      {with({"-o", dir + "/out.exr", "--checkpoint", "10"}), "--checkpoint " + checkpoint + ": is a FIFO, not a regular file"},
      {{"info", writeCage(dir), "--subdiv", "catmull-clark", "--displace", "/dev/zero"}, "/dev/zero" + chr},
      {with({"-o", dir + "/env.exr", "--environment", "/dev/zero"}), "/dev/zero" + chr},
      {with({"-o", dir + "/fit.exr", "-i", "multibounce", "-p", "mapping=fitted", "-p", "fit=/dev/zero"}), "/dev/zero" + chr},
      {with({"-o", dir + "/map.exr", "-i", "containment", "-p", "distance=0.5", "-p", "map=/dev/zero"}), "/dev/zero" + chr},
      {{"compare", scene, "-o", dir + "/cmp", "--res", "8x8", "-c", "ao", "-q", "--reference", "/dev/zero"}, "/dev/zero" + chr},
      {{"merge", dir + "/merged.exr", "/dev/zero"}, "merge: TILE /dev/zero" + chr},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(cases[i].says);
    expectRefusal(runCli(cases[i].args, dir + "/err" + std::to_string(i) + ".txt"), {cases[i].says});
  }
}

}  // namespace
}  // namespace obscura::test
