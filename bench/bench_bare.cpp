// obscura_bench_bare: Obscura's render loop against a bare Embree loop that
// does nothing but generate and trace the same rays (issue 13, item 5).
//
// The bare loop shares nothing with the renderer's per-sample code: its own
// pinhole camera (from the Camera's matrix and yfov only), its own counter-
// based hash RNG (one PCG-style hash per sample, then an LCG step per draw),
// its own orthonormal basis and cosine warp (r = sqrt(u1), phi = 2 pi u2), no
// Obscura sampler, camera walk, SurfaceHit or integrator. It only takes the
// RTCScene from Obscura's loader. It walks the frame the way any tiled
// renderer would: 16x16 tiles over tbb::parallel_for in a task_arena of
// --threads threads, each tile pixel-major in batches of 256 camera samples:
//   camera rays -> rtcIntersect1M (coherent) -> for each hit one cosine-
//   weighted AO ray about the geometric normal, from o + t d pushed off the
//   surface by 2^-16 of its magnitude, over (0, R] with R = the `ao`
//   default (inf) -> rtcOccluded1M (incoherent).
// So it traces the same rays as `obscura render -i ao` (rays=1): the same
// camera rays in distribution (box-filtered pinhole samples), one AO ray per
// camera hit, cosine-distributed (about Ng rather than the shading normal:
// the same cost for Embree). The ray counts are printed side by side.
//
// In the same run, interleaved, obscura::render() with the registered `ao`
// integrator at the same resolution, spp, camera and threads: once with
// AOVs (as `obscura render`), once without the albedo AOV (--no-albedo), once
// without any (--no-aovs). Mrays/s = (camera +
// AO rays) / median wall seconds of the loop (render(): RenderStats::seconds,
// its render loop; the bare loop: its parallel_for, arena included). With
// --exe (default: the `obscura` next to this bench's directory) and a file
// scene it also times the whole process `obscura render SCENE -q -i ao ...`
// (wall clock and the child's user + system CPU seconds, EXR written to
// /tmp, to a path that does not exist yet: a new frame) and prints its
// Mrays/s, once with the default EXR compression (zip) and once with
// --compression none, so the write's share shows. With
// --before-exe OTHER, OTHER's process is timed the same way in the same
// runs (e.g. a build of main: before/after in one run).
//
// --trade: the sampler's trade. The bare loop once more with its hash RNG
// and once with Obscura's Owen-scrambled Sobol' sampler in its place (the
// renderer's dimensions: the pixel filter's pair and the first integrator
// pair; everything else the same), at several spp on a small image, each
// rendered with --trade-seeds seeds; both are unbiased, so the error is the
// per-pixel variance over the seeds. Printed: time, RMSE of the
// premultiplied AO pass, and RMSE x sqrt(time) - the error at equal time if
// the error falls as 1/sqrt(time) (smaller is better).
//
// Run:   build/bench/obscura_bench_bare                      viking (if present) + generated, 1024x1024, 32 spp, 2 threads
//        build/bench/obscura_bench_bare --scene viking --runs 7
//        build/bench/obscura_bench_bare --scene viking --trade --runs 1
//        perf record -g -- build/bench/obscura_bench_bare --scene viking --profile bare --runs 10
// The viking room is skipped with a note when ../shared/scenes is absent.
#include <CLI/CLI.hpp>
#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "bench/common.h"
#include <obscura/error.h>
#include "core/image/film.h"
#include <obscura/sampler.h>

using namespace obscura;
using namespace obscura::bench;

namespace {

constexpr int kTile = 16;
constexpr size_t kBatch = 256;
constexpr float kTwoPi = 6.28318530717958647692f;

// --- the bare loop's own pieces ---------------------------------------------

struct V3 {
  float x, y, z;
};
inline V3 add(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 mul(V3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
inline float dot3(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 unit(V3 a) { return mul(a, 1.0f / std::sqrt(dot3(a, a))); }

// A pinhole camera: dir(fx, fy) = normalize(c + fx r + fy d), film position in
// pixels, y down; the glTF convention (looks down -Z, +Y up).
struct Pinhole {
  V3 org, c, r, d;
  Pinhole(const Camera& cam, int w, int h) {
    const auto col = [&](int j) { return V3{cam.toWorld.m[0][j], cam.toWorld.m[1][j], cam.toWorld.m[2][j]}; };
    const float ty = std::tan(0.5f * cam.yfov), tx = ty * float(w) / float(h);
    org = col(3);
    r = mul(col(0), 2.0f * tx / float(w));
    d = mul(col(1), -2.0f * ty / float(h));
    c = add(add(mul(col(2), -1.0f), mul(col(0), -tx)), mul(col(1), ty));
  }
  V3 dir(float fx, float fy) const { return unit(add(c, add(mul(r, fx), mul(d, fy)))); }
};

// Counter-based RNG: a PCG output hash of (seed, pixel, sample) gives the
// state, an LCG step per draw. Four draws per sample.
struct HashRng {
  uint32_t s;
  HashRng(uint32_t pixel, uint32_t sample) {
    uint32_t x = pixel * 0x9e3779b1U ^ (sample + 0x7f4a7c15U) * 0x85ebca77U;
    x = x * 747796405U + 2891336453U;
    x = ((x >> ((x >> 28) + 4)) ^ x) * 277803737U;
    s = (x >> 22) ^ x;
  }
  float next() {
    s = s * 747796405U + 2891336453U;
    uint32_t x = ((s >> ((s >> 28) + 4)) ^ s) * 277803737U;
    x = (x >> 22) ^ x;
    return float(x >> 8) * 0x1p-24f;
  }
};

// The two sample sources the bare loop can run with: its hash RNG, or, for
// the sampler trade only, Obscura's sampler at the renderer's dimensions.
enum class Rng { Hash, Sobol };

struct BareSettings {
  int width = 1024, height = 1024, spp = 32, threads = 2;
  float aoDistance = INFINITY;
  Rng rng = Rng::Hash;
  uint32_t seed = 0;
};

struct BareTally {
  uint64_t camera = 0, ao = 0, open = 0;
};

struct BareBuffers {
  BareBuffers() : cam(kBatch), occ(kBatch), pix(kBatch) {}
  AlignedArray<RTCRayHit> cam;
  AlignedArray<RTCRay> occ;
  AlignedArray<uint32_t> pix;  // lane -> pixel index within the tile (image mode)
  BareTally tally;
};

class BareLoop {
 public:
  BareLoop(RTCScene scene, const Camera& cam, const BareSettings& s)
      : scene_(scene), camera_(cam, s.width, s.height), tnear_(cam.znear), tfar_(cam.zfar), s_(s),
        sampler_(s.seed) {}

  // One frame; returns the loop's wall seconds. With `image` (width x
  // height), the premultiplied AO pass: open AO rays / spp per pixel.
  double run(BareTally& tally, std::vector<float>* image = nullptr) {
    for (auto& b : buffers_) b.tally = {};
    if (image) image->assign(size_t(s_.width) * size_t(s_.height), 0.0f);
    const int tx = (s_.width + kTile - 1) / kTile, ty = (s_.height + kTile - 1) / kTile;
    const auto t0 = std::chrono::steady_clock::now();
    tbb::task_arena arena(s_.threads);
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<int>(0, tx * ty, 1), [&](const tbb::blocked_range<int>& r) {
        BareBuffers& b = buffers_.local();
        for (int t = r.begin(); t != r.end(); ++t) {
          if (s_.rng == Rng::Hash)
            tile<Rng::Hash>(b, t % tx, t / tx, image);
          else
            tile<Rng::Sobol>(b, t % tx, t / tx, image);
        }
      });
    });
    const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    tally = {};
    for (const auto& b : buffers_) {
      tally.camera += b.tally.camera;
      tally.ao += b.tally.ao;
      tally.open += b.tally.open;
    }
    return sec;
  }

 private:
  template <Rng kRng>
  void tile(BareBuffers& b, int tileX, int tileY, std::vector<float>* image) const {
    const int x0 = tileX * kTile, y0 = tileY * kTile;
    const int x1 = std::min(x0 + kTile, s_.width), y1 = std::min(y0 + kTile, s_.height);
    const uint64_t total = uint64_t(x1 - x0) * uint64_t(y1 - y0) * uint64_t(s_.spp);
    RTCIntersectContext cc, oc;
    rtcInitIntersectContext(&cc);
    cc.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    rtcInitIntersectContext(&oc);
    oc.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    int px = x0, py = y0;
    uint32_t si = 0;
    uint32_t key = kRng == Rng::Sobol ? sampler_.pixelKey(uint32_t(px), uint32_t(py)) : 0;
    // The AO draws of each lane, made with its camera draws (hash) or read
    // from the Sobol' sampler at the lane's (pixel, sample).
    float au[kBatch], av[kBatch];
    for (uint64_t begin = 0; begin < total; begin += kBatch) {
      const size_t n = size_t(std::min<uint64_t>(kBatch, total - begin));
      for (size_t i = 0; i < n; ++i) {
        float jx, jy;
        if constexpr (kRng == Rng::Hash) {
          HashRng rng(uint32_t(py) * uint32_t(s_.width) + uint32_t(px) + s_.seed * 0x632be5abU, si);
          jx = rng.next(), jy = rng.next(), au[i] = rng.next(), av[i] = rng.next();
        } else {
          const Sample2 f = Sampler::get2D(key, si, kDimPixelFilter);
          const Sample2 a = Sampler::get2D(key, si, kFirstIntegratorDim);
          jx = f.u, jy = f.v, au[i] = a.u, av[i] = a.v;
        }
        const V3 d = camera_.dir(float(px) + jx, float(py) + jy);
        RTCRayHit& rh = b.cam.p[i];
        rh.ray.org_x = camera_.org.x, rh.ray.org_y = camera_.org.y, rh.ray.org_z = camera_.org.z;
        rh.ray.dir_x = d.x, rh.ray.dir_y = d.y, rh.ray.dir_z = d.z;
        rh.ray.tnear = tnear_, rh.ray.tfar = tfar_, rh.ray.time = 0.0f;
        rh.ray.mask = 0xffffffffU, rh.ray.id = 0, rh.ray.flags = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        b.pix.p[i] = uint32_t((py - y0) * kTile + (px - x0));
        if (++si == uint32_t(s_.spp)) {
          si = 0;
          if (++px == x1) px = x0, ++py;
          if constexpr (kRng == Rng::Sobol) key = sampler_.pixelKey(uint32_t(px), uint32_t(py));
        }
      }
      rtcIntersect1M(scene_, &cc, b.cam.p, unsigned(n), sizeof(RTCRayHit));

      size_t m = 0;
      uint32_t aoPix[kBatch];
      for (size_t i = 0; i < n; ++i) {
        const RTCRayHit& rh = b.cam.p[i];
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
        const V3 o{rh.ray.org_x, rh.ray.org_y, rh.ray.org_z}, d{rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z};
        const V3 p = add(o, mul(d, rh.ray.tfar));
        V3 n3{rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z};
        n3 = unit(n3);
        if (dot3(n3, d) > 0.0f) n3 = mul(n3, -1.0f);
        // Orthonormal basis about n (Duff et al. 2017's branchless form).
        const float sg = std::copysign(1.0f, n3.z), a = -1.0f / (sg + n3.z), bb = n3.x * n3.y * a;
        const V3 t1{1.0f + sg * n3.x * n3.x * a, sg * bb, -sg * n3.x}, t2{bb, sg + n3.y * n3.y * a, -n3.y};
        const float r = std::sqrt(au[i]), phi = kTwoPi * av[i];
        const float lx = r * std::cos(phi), ly = r * std::sin(phi), lz = std::sqrt(std::max(0.0f, 1.0f - au[i]));
        const V3 w = add(add(mul(t1, lx), mul(t2, ly)), mul(n3, lz));
        const float mag = std::max(std::abs(p.x), std::max(std::abs(p.y), std::abs(p.z)));
        const V3 org = add(p, mul(n3, std::max(mag * 0x1p-16f, 1e-30f)));
        RTCRay& q = b.occ.p[m];
        q.org_x = org.x, q.org_y = org.y, q.org_z = org.z, q.tnear = 0.0f;
        q.dir_x = w.x, q.dir_y = w.y, q.dir_z = w.z, q.time = 0.0f;
        q.tfar = s_.aoDistance, q.mask = 0xffffffffU, q.id = 0, q.flags = 0;
        aoPix[m] = b.pix.p[i];
        ++m;
      }
      rtcOccluded1M(scene_, &oc, b.occ.p, unsigned(m), sizeof(RTCRay));
      uint64_t open = 0;
      for (size_t j = 0; j < m; ++j) {
        const bool o = b.occ.p[j].tfar >= 0.0f;
        open += o ? 1 : 0;
        if (image && o) {
          const uint32_t lp = aoPix[j];
          (*image)[size_t(y0 + int(lp) / kTile) * size_t(s_.width) + size_t(x0 + int(lp) % kTile)] +=
              1.0f / float(s_.spp);
        }
      }
      b.tally.camera += n;
      b.tally.ao += m;
      b.tally.open += open;
    }
  }

  RTCScene scene_;
  Pinhole camera_;
  float tnear_, tfar_;
  BareSettings s_;
  Sampler sampler_;
  tbb::enumerable_thread_specific<BareBuffers> buffers_;
};

// --- the renderer --------------------------------------------------------------

struct RenderRun {
  BenchIntegrator integ{"ao", {}};
  RenderSettings settings;
  double run(const BenchScene& bs, BareTally& tally) const {
    RenderStats st;
    const Film f = integ.render(*bs.scene, bs.camera, settings, st);
    tally.camera = st.rays.camera;
    tally.ao = st.rays.occlusion;
    return st.seconds;
  }
};

// The path of `obscura` (the CLI) next to this bench's build directory.
std::string defaultExe() {
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return "";
  const auto exe = self.parent_path().parent_path() / "obscura";
  return std::filesystem::exists(exe) ? exe.string() : "";
}

struct Options : CommonOptions {
  Options() {
    res = "1024x1024";
    spp = 32;
    runs = 5;
    threads = 2;
  }
  std::string exe = defaultExe();
  std::string beforeExe;
  bool noProcess = false;
  bool trade = false;
  std::string tradeRes = "256x256";
  std::string tradeSpp = "4,16,64";
  int tradeSeeds = 8;
  std::string only;  // --profile: run just this loop (bare, aovs, no-aovs)
};

double mrays(const BareTally& t, double sec) { return double(t.camera + t.ao) / sec * 1e-6; }

// CPU seconds (user + system) of the waited-for child processes so far: the
// whole process's CPU time, start-up and EXR write included.
double childCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_CHILDREN, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

void benchScene(const std::string& which, const Options& o, int width, int height, int threads) {
  std::printf("\n== scene: %s\n", which.c_str());
  BenchScene bs = loadScene(which, float(width) / float(height));
  std::printf("   source     %s (%zu triangles)\n", bs.source.c_str(), bs.triangles);

  BareSettings bset;
  bset.width = width, bset.height = height, bset.spp = o.spp, bset.threads = threads;
  BareLoop bare(bs.scene->rtcScene(), bs.camera, bset);
  RenderRun withAovs, noAlbedo, noAovs;
  withAovs.settings = benchRenderSettings(width, height, o.spp, threads);
  withAovs.settings.aovs = true;  // as `obscura render` (default)
  noAlbedo.settings = withAovs.settings;
  noAlbedo.settings.albedoAov = false;  // --no-albedo
  noAovs.settings = benchRenderSettings(width, height, o.spp, threads);
  const bool process = !o.noProcess && !o.exe.empty() && which != "generated";
  // The processes timed each run: this build's `obscura` (and --before-exe's),
  // each with the default compression (zip) and with none.
  struct ProcessCase {
    std::string label, cmd;
    std::vector<double> wall, cpu;
  };
  std::vector<ProcessCase> cases;
  const std::string output = "/tmp/obscura_bench_bare_" + std::to_string(getpid()) + ".exr";
  if (process) {
    const auto command = [&](const std::string& exe, const char* extra) {
      return exe + " render '" + bs.source + "' -q -i ao --res " + std::to_string(width) + "x" +
             std::to_string(height) + " --spp " + std::to_string(o.spp) + " --threads " + std::to_string(threads) +
             extra + " -o " + output;
    };
    for (const std::string& exe : {o.exe, o.beforeExe}) {
      if (exe.empty()) continue;
      const std::string who = exe == o.exe ? "whole process" : "before: process";
      cases.push_back({who + " (zip, default)", command(exe, ""), {}, {}});
      cases.push_back({who + " (--compression none)", command(exe, " --compression none"), {}, {}});
      if (exe == o.exe)
        cases.push_back({who + " (none, --no-albedo)", command(exe, " --compression none --no-albedo"), {}, {}});
    }
  }

  {  // warm-up: threads, buffers, first touches
    BareSettings w = bset;
    w.spp = 1;
    BareLoop wb(bs.scene->rtcScene(), bs.camera, w);
    BareTally t;
    wb.run(t);
    RenderRun wr;
    wr.settings = noAovs.settings;
    wr.settings.spp = 1;
    wr.run(bs, t);
  }

  // Wall seconds and process CPU seconds of each run: on a shared machine
  // the CPU seconds (Mrays per CPU-second) are what other processes disturb
  // least.
  std::vector<double> tb, ta, tl, tn, cb, ca, cl, cn;
  BareTally kb, ka, kl, kn;
  const auto timed = [](std::vector<double>& cpu, auto&& f) {
    const double c0 = processCpuSeconds();
    const double sec = f();
    cpu.push_back(processCpuSeconds() - c0);
    return sec;
  };
  if (!o.only.empty()) {
    // --profile: one loop alone, --runs times, for a CPU profile
    // (perf record -- obscura_bench_bare --profile bare): its samples are
    // that loop's and the warm-up's only.
    for (int r = 0; r < o.runs; ++r) {
      const double sec = o.only == "bare"        ? bare.run(kb)
                         : o.only == "aovs"      ? withAovs.run(bs, ka)
                         : o.only == "no-albedo" ? noAlbedo.run(bs, kl)
                                                 : noAovs.run(bs, kn);
      std::printf("   run %d/%d: %s %.3f s\n", r + 1, o.runs, o.only.c_str(), sec);
    }
    return;
  }
  for (int r = 0; r < o.runs; ++r) {
    tb.push_back(timed(cb, [&] { return bare.run(kb); }));
    ta.push_back(timed(ca, [&] { return withAovs.run(bs, ka); }));
    tl.push_back(timed(cl, [&] { return noAlbedo.run(bs, kl); }));
    tn.push_back(timed(cn, [&] { return noAovs.run(bs, kn); }));
    for (ProcessCase& pc : cases) {
      // A new frame: the output does not exist yet. (Renaming the finished
      // file over an existing 64 MiB one adds ext4's work - the flush it
      // starts on a replacing rename and the old file's truncation - about
      // 40 ms here, which has nothing to do with rendering.)
      std::filesystem::remove(output);
      const auto t0 = std::chrono::steady_clock::now();
      const double c0 = childCpuSeconds();
      if (std::system(pc.cmd.c_str()) != 0) throw Error("failed: " + pc.cmd);
      pc.wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      pc.cpu.push_back(childCpuSeconds() - c0);
    }
    std::printf("   run %d/%d: bare %.3f s, render %.3f s, render --no-albedo %.3f s, render --no-aovs %.3f s", r + 1,
                o.runs, tb.back(), ta.back(), tl.back(), tn.back());
    for (const ProcessCase& pc : cases) std::printf(", %s %.3f s", pc.label.c_str(), pc.wall.back());
    std::printf("\n");
    std::fflush(stdout);
  }
  if (!cases.empty()) std::filesystem::remove(output);
  double load[3] = {0, 0, 0};
  if (getloadavg(load, 3) < 0) load[0] = load[1] = load[2] = -1;
  std::printf("   load average after the runs: %.2f %.2f %.2f (1, 5, 15 min)\n", load[0], load[1], load[2]);
  const double mb = mrays(kb, median(tb));
  std::printf("   rays: bare %llu camera + %llu AO; render %llu + %llu (AO rays differ by the hit set only)\n",
              (unsigned long long)kb.camera, (unsigned long long)kb.ao, (unsigned long long)ka.camera,
              (unsigned long long)ka.ao);
  const double cpuB = mrays(kb, median(cb));
  std::printf("   %-44s %8s %8s %7s   %8s %8s %7s\n", "", "wall s", "Mrays/s", "/ bare", "CPU s", "Mr/CPUs", "/ bare");
  const auto row = [&](const std::string& name, const BareTally& k, const std::vector<double>& w,
                       const std::vector<double>& c) {
    std::printf("   %-44s %8.3f %8.2f %6.1f%%", name.c_str(), median(w), mrays(k, median(w)), 100.0 * mrays(k, median(w)) / mb);
    if (!c.empty())
      std::printf("   %8.3f %8.2f %6.1f%%", median(c), mrays(k, median(c)), 100.0 * mrays(k, median(c)) / cpuB);
    std::printf("\n");
  };
  row("bare Embree loop", kb, tb, cb);
  row("render() loop, AOVs (CLI default)", ka, ta, ca);
  row("render() loop, --no-albedo", kl, tl, cl);
  row("render() loop, --no-aovs", kn, tn, cn);
  for (const ProcessCase& pc : cases) row(pc.label, ka, pc.wall, pc.cpu);
  std::printf("   (medians of %d runs, interleaved; Mr/CPUs = Mrays per CPU-second of this process (the loop's\n"
              "   threads; the whole process: the child's user + system seconds); goals: render() loop >= 90%%,\n"
              "   whole process >= 80%% of bare)\n", o.runs);
  for (const ProcessCase& pc : cases) std::printf("   %s: %s\n", pc.label.c_str(), pc.cmd.c_str());
  std::fflush(stdout);

  if (!o.trade) return;
  // The sampler's trade (see the header comment).
  std::printf("\n   sampler trade: bare loop with its hash RNG vs Obscura's Sobol' sampler, %s\n", o.tradeRes.c_str());
  CommonOptions tr;
  tr.res = o.tradeRes;
  const BenchSize ts = checkCommonOptions(tr);
  // Both samplers are unbiased, so a render's mean squared error is its
  // variance: estimated per pixel from --trade-seeds independent renders
  // (seeds 0..K-1) and averaged over the pixels - no reference image, whose
  // own noise would hide the smaller of the two errors.
  const int seeds = std::max(2, o.tradeSeeds);
  std::printf("   %6s %-6s %9s %10s %14s\n", "spp", "rng", "s", "RMSE", "RMSE*sqrt(s)");
  for (const std::string& sppText : splitCommaList(o.tradeSpp)) {
    const int spp = std::atoi(sppText.c_str());
    if (spp < 1) throw Error("--trade-spp: bad count '" + sppText + "'");
    for (Rng rng : {Rng::Hash, Rng::Sobol}) {
      const size_t pixels = size_t(ts.width) * size_t(ts.height);
      std::vector<double> sum(pixels, 0.0), sum2(pixels, 0.0), secs;
      std::vector<float> img;
      BareTally t;
      for (int k = 0; k < seeds; ++k) {
        BareSettings set;
        set.width = ts.width, set.height = ts.height, set.threads = threads, set.spp = spp, set.rng = rng;
        set.seed = uint32_t(k);
        BareLoop l(bs.scene->rtcScene(), bs.camera, set);
        secs.push_back(l.run(t, &img));
        for (size_t i = 0; i < pixels; ++i) sum[i] += img[i], sum2[i] += double(img[i]) * img[i];
      }
      double var = 0;
      for (size_t i = 0; i < pixels; ++i) var += (sum2[i] - sum[i] * sum[i] / seeds) / (seeds - 1);
      const double s = median(secs), e = std::sqrt(var / double(pixels));
      std::printf("   %6d %-6s %9.4f %10.5f %14.6f\n", spp, rng == Rng::Hash ? "hash" : "sobol", s, e, e * std::sqrt(s));
      std::fflush(stdout);
    }
  }
  std::printf("   RMSE = sqrt(mean over the pixels of the variance of the premultiplied pass (open AO rays / spp)\n"
              "   over %d seeds); s = median loop seconds; RMSE*sqrt(s): the error at equal time if it falls as\n"
              "   1/sqrt(time), smaller is better.\n",
              seeds);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obscura_bench_bare: obscura::render's ao loop vs a bare Embree loop tracing the same rays"};
  Options o;
  addCommonOptions(app, o, "Smoke run: 256x256, 4 spp, 1 run unless given");
  app.add_option("--exe", o.exe, "The obscura CLI, to time the whole process (default: " + o.exe + ")");
  app.add_option("--before-exe", o.beforeExe,
                 "Another obscura CLI (e.g. a build of main) whose process is timed in the same runs");
  app.add_flag("--no-process", o.noProcess, "Do not time the whole process");
  app.add_flag("--trade", o.trade, "Also measure the sampler's trade: hash RNG vs Sobol' in the bare loop");
  app.add_option("--trade-res", o.tradeRes, "Resolution of the trade's images (default 256x256)");
  app.add_option("--trade-spp", o.tradeSpp, "Comma list of spp for the trade (default 4,16,64)");
  app.add_option("--trade-seeds", o.tradeSeeds, "Independent renders per trade cell (default 8)");
  app.add_option("--profile", o.only, "Run only this loop --runs times, nothing else timed (for perf record)")
      ->check(CLI::IsMember({"bare", "aovs", "no-albedo", "no-aovs"}))
      ->excludes("--trade");
  CLI11_PARSE(app, argc, argv);
  try {
    if (o.quick) {
      if (!app.count("--res")) o.res = "256x256";
      if (!app.count("--spp")) o.spp = 4;
      if (!app.count("--runs")) o.runs = 1;
    }
    const auto [width, height] = checkCommonOptions(o);
    const ThreadLimit limit(o.threads);
    std::printf("obscura_bench_bare: %dx%d, %d spp, ao (rays=1, distance inf)\n", width, height, o.spp);
    printMachine(limit.threads());
    for (const std::string& sc : o.scenes) {
      if (sc == "viking" && !std::filesystem::exists(vikingRoomPath())) {
        std::printf("\n== scene: viking: skipped (%s is absent)\n", vikingRoomPath().c_str());
        continue;
      }
      benchScene(sc, o, width, height, limit.threads());
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_bare: error: %s\n", e.what());
    return 1;
  }
}
