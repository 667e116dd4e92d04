// Writing a pass's EXR: every lossless compression OpenEXR offers, a few zlib
// levels and thread counts, timed on the film of a real render (noise and
// edges compress as they do in production; a synthetic gradient would
// flatter every codec), against the OpenImageIO writer Obscura used before
// (interleaved bands of 64 scanlines, zip). Prints, per candidate, the
// median write time over --runs and the file's size: the table in README
// "Start-up and file speed".
//
//   obscura_bench_exr_write [--res 1920x1080] [--spp 16] [--runs 10] [--threads 0] [--cryptomatte]
#include <OpenImageIO/imageio.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "bench/common.h"
#include <obscura/error.h>
#include "core/image/image_io.h"

using namespace obscura;
using namespace obscura::bench;

namespace {

// The writer core/image_io used before OpenEXR directly: OpenImageIO, the
// planes interleaved into bands of 64 scanlines.
void writeThroughOiio(const std::string& path, const Film& film) {
  const std::vector<int>& chans = film.channels();
  const int nc = int(chans.size());
  OIIO::ImageSpec spec(film.width(), film.height(), nc, OIIO::TypeDesc::FLOAT);
  spec.channelnames.clear();
  for (int c : chans) spec.channelnames.emplace_back(film.name(c));
  spec.attribute("compression", "zip");
  auto out = OIIO::ImageOutput::create("openexr");
  if (!out || !out->open(path, spec)) throw Error(path + ": cannot open through OpenImageIO");
  const int band = 64;
  const size_t w = size_t(film.width());
  std::vector<float> rows(w * size_t(band) * size_t(nc));
  for (int y0 = 0; y0 < film.height(); y0 += band) {
    const int y1 = std::min(film.height(), y0 + band);
    for (int y = y0; y < y1; ++y)
      for (int i = 0; i < nc; ++i) {
        const float* src = film.plane(chans[size_t(i)]) + size_t(y) * w;
        float* dst = rows.data() + size_t(y - y0) * w * size_t(nc) + size_t(i);
        for (size_t x = 0; x < w; ++x) dst[x * size_t(nc)] = src[x];
      }
    if (!out->write_scanlines(y0, y1, 0, OIIO::TypeDesc::FLOAT, rows.data())) throw Error(path + ": write failed");
  }
  out->close();
}

struct Candidate {
  std::string label;
  ExrCompression compression;
  int zipLevel;  // 0: OpenEXR's default
  int threads;   // 0: all
  bool oiio = false;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"EXR write time and size per compression, on a rendered film with every AOV"};
  CommonOptions common;
  common.res = "1920x1080";
  common.spp = 16;
  common.runs = 10;
  addCommonOptions(app, common, "smoke run: 320x180, 1 spp, 2 runs");
  bool crypto = false;
  bool half = false;
  app.add_flag("--cryptomatte", crypto, "Also write Cryptomatte object and material layers (6 ranks: 12 more channels each)");
  app.add_flag("--half", half, "Half channels (as --half)");
  CLI11_PARSE(app, argc, argv);
  try {
    if (common.quick) common.res = "320x180", common.spp = 1, common.runs = 2;
    if (common.scenes.empty()) common.scenes = {OBSCURA_DEFAULT_SCENE};
    const BenchSize size = checkCommonOptions(common);
    const ThreadLimit threads(common.threads);
    printMachine(threads.threads());
    const BenchScene scene = loadScene(common.scenes.front(), float(size.width) / float(size.height));
    RenderSettings s = benchRenderSettings(size.width, size.height, common.spp, threads.threads());
    s.aovs = true;  // the default channel set: R G B A Z N.XYZ albedo.RGB shaded.RGB
    if (crypto) s.cryptomatte = parseCryptomatte("object,material", kDefaultCryptomatteRanks);
    RenderStats stats;
    const Film film = BenchIntegrator("ao", {}).render(*scene.scene, scene.camera, s, stats);
    std::printf("film: %s, %dx%d, %d spp, %zu channels (%s)\n", scene.label.c_str(), film.width(), film.height(),
                common.spp, film.channels().size(), half ? "half but N, Z" : "float");

    const int n = threads.threads();
    std::vector<Candidate> cands = {{"openimageio zip (before)", ExrCompression::Zip, 0, n, true}};
    for (int t : {1, n}) {
      cands.push_back({"none", ExrCompression::None, 0, t});
      cands.push_back({"rle", ExrCompression::Rle, 0, t});
      for (int level : {1, 0}) cands.push_back({"zips", ExrCompression::Zips, level, t});
      for (int level : {1, 0, 6}) cands.push_back({"zip", ExrCompression::Zip, level, t});
      cands.push_back({"piz", ExrCompression::Piz, 0, t});
    }
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("obscura_bench_exr_" + std::to_string(getpid()));
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "pass.exr").string();
    // Wall time, and the process's CPU time (user + system, all threads),
    // which a busy shared machine inflates less.
    std::printf("%-26s %5s %7s %10s %10s %10s %7s\n", "compression", "level", "threads", "median s", "cpu s", "MiB", "ratio");
    const double raw = double(film.width()) * film.height() * double(film.channels().size()) * 4.0;
    for (const Candidate& c : cands) {
      ExrOptions o;
      o.half = half;
      o.compression = c.compression;
      o.zipLevel = c.zipLevel;
      o.threads = c.threads;
      std::vector<double> t, cpu;
      for (int r = 0; r < common.runs; ++r) {
        const double c0 = processCpuSeconds();
        const auto t0 = std::chrono::steady_clock::now();
        if (c.oiio) writeThroughOiio(path, film);
        else writeExr(path, film, o);
        t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        cpu.push_back(processCpuSeconds() - c0);
      }
      const double bytes = double(std::filesystem::file_size(path));
      std::printf("%-26s %5s %7d %10.4f %10.4f %10.2f %7.2f\n", c.label.c_str(),
                  c.compression == ExrCompression::Zip || c.compression == ExrCompression::Zips
                      ? (c.zipLevel ? std::to_string(c.zipLevel).c_str() : "dflt")
                      : "-",
                  c.threads, median(t), median(cpu), bytes / (1 << 20), raw / bytes);
    }
    std::filesystem::remove_all(dir);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_exr_write: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
