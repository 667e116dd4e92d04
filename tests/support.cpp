#include "tests/support.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>

#include "core/error.h"

extern char** environ;

namespace obscura::test {

std::string tempDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("obscura_test_" + std::to_string(::getpid())) / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

std::string sharedScenesDir() {
  const char* env = std::getenv("OBSCURA_SCENES");
  return env && *env ? std::string(env) : std::string(OBSCURA_DEFAULT_SCENES);
}

std::string sharedScene(const std::string& rel) { return sharedScenesDir() + "/" + rel; }

bool sharedScenesRequired() {
  const char* env = std::getenv("OBSCURA_REQUIRE_SCENES");
  return env && *env && std::string(env) != "0";
}

std::string missingSharedScene(const std::string& path) {
  if (std::filesystem::exists(path)) return "";
  return "skipped: needs the third-party scene " + path +
         " (not in the repository; set OBSCURA_SCENES to the folder holding the shared scenes)";
}

int addGreyMaterial(Scene& scene, float a) {
  Material m;
  m.name = "grey";
  m.baseColorFactor = Vec3(a, a, a);
  scene.materials.push_back(m);
  return int(scene.materials.size()) - 1;
}

void sphereCavityMesh(float rs, double alpha, int rings, int segments, std::vector<Vec3>& pos, std::vector<Vec3>& nrm,
                      std::vector<uint32_t>& idx) {
  pos.clear(), nrm.clear(), idx.clear();
  // Ring r at polar angle theta_r from +Z: theta_0 = alpha (hole edge) to
  // theta_rings = pi (the -Z pole, one vertex).
  for (int r = 0; r <= rings; ++r) {
    const double theta = alpha + (M_PI - alpha) * double(r) / rings;
    const int n = r == rings ? 1 : segments;
    for (int s = 0; s < n; ++s) {
      const double phi = 2.0 * M_PI * double(s) / segments;
      const Vec3 p(float(rs * std::sin(theta) * std::cos(phi)), float(rs * std::sin(theta) * std::sin(phi)),
                   float(rs * std::cos(theta)));
      pos.push_back(r == rings ? Vec3(0, 0, -rs) : p);
      nrm.push_back(r == rings ? Vec3(0, 0, 1) : normalize(-p));
    }
  }
  const auto at = [&](int r, int s) { return uint32_t(r * segments + (s % segments)); };
  for (int r = 0; r + 1 < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      idx.insert(idx.end(), {at(r, s), at(r + 1, s), at(r + 1, s + 1)});
      idx.insert(idx.end(), {at(r, s), at(r + 1, s + 1), at(r, s + 1)});
    }
  const uint32_t pole = uint32_t(rings * segments);
  for (int s = 0; s < segments; ++s) idx.insert(idx.end(), {at(rings - 1, s), pole, at(rings - 1, s + 1)});
}

void addSphereCavity(Scene& scene, float rs, double alpha, int rings, int segments, int material) {
  std::vector<Vec3> pos, nrm;
  std::vector<uint32_t> idx;
  sphereCavityMesh(rs, alpha, rings, segments, pos, nrm, idx);
  scene.addWorldPrimitive(pos, idx, nrm, {}, material);
}

void addPlane(Scene& scene, float h, float z) {
  scene.addWorldPrimitive({{-h, -h, z}, {h, -h, z}, {h, h, z}, {-h, h, z}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
}

SubdivisionCage planeCage(int n) {
  SubdivisionCage c;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      c.positions.emplace_back(float(x) / n, float(y) / n, 0.0f);
      c.uvs.insert(c.uvs.end(), {float(x) / n, float(y) / n});
    }
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int a = y * (n + 1) + x;
      for (const int i : {a, a + 1, a + n + 2, a + n + 1}) c.faceIndices.push_back(i), c.uvIndices.push_back(i);
      c.faceSizes.push_back(4);
    }
  return c;
}

RTCRayHit traceClosest(const Scene& scene, Vec3 org, Vec3 dir) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh{};
  rh.ray.org_x = org.x, rh.ray.org_y = org.y, rh.ray.org_z = org.z;
  rh.ray.dir_x = dir.x, rh.ray.dir_y = dir.y, rh.ray.dir_z = dir.z;
  rh.ray.tfar = kInfinity;
  rh.ray.mask = ~0u;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene.rtcScene(), &ctx, &rh);
  return rh;
}

RenderSettings passSettings(int w, int h, int spp, uint32_t seed) {
  RenderSettings s;
  s.width = w;
  s.height = h;
  s.spp = spp;
  s.seed = seed;
  s.aovs = false;
  return s;
}

Film renderWith(const Scene& scene, const Camera& camera, const std::string& integrator,
                const std::vector<std::string>& params, const RenderSettings& settings, RenderStats* stats) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find(integrator);
  ParamSet p(d.params, d.name);
  for (const auto& a : params) p.setAssignment(a);
  auto integ = d.create(p);
  RenderStats local;
  return render(scene, camera, *integ, d.needs(p), settings, stats ? *stats : local);
}

double meanCovered(const Film& film, int channel, size_t* count) {
  double sum = 0;
  size_t n = 0;
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x)
      if (film.at(kA, x, y) == 1.0f) {
        sum += film.at(channel, x, y);
        ++n;
      }
  if (count) *count = n;
  return n ? sum / double(n) : NAN;
}

SubdivisionCage cubeCage() {
  SubdivisionCage c;
  for (int i = 0; i < 8; ++i) c.positions.emplace_back(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1);
  c.faceIndices = {0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5};
  c.faceSizes.assign(6, 4);
  return c;
}

void expectNoRayEscapes(const Scene& scene, Vec3 eye, Vec3 target) {
  const Camera cam = makeLookAtCamera(eye, target, Vec3(0, 0, 1), 2.5f, "inside");
  const Film f = renderWith(scene, cam, "ao", {"rays=8"}, passSettings(16, 16, 16));
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) ASSERT_EQ(f.at(kR, x, y), 0.0f) << "pixel " << x << "," << y;
}

void expectNoRayEscapes(const SubdividedMesh& m) {
  Scene scene;
  scene.addWorldPrimitive(m.positions, m.triangles, m.normals, {}, -1);
  scene.setRobust(true);
  scene.commit();
  expectNoRayEscapes(scene);
}

// --- files ------------------------------------------------------------------

std::vector<unsigned char> readBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void writeBytes(const std::string& path, const void* data, size_t n) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(static_cast<const char*>(data), std::streamsize(n));
  ASSERT_TRUE(out.good()) << path;
}

void writeText(const std::string& path, const std::string& text) { writeBytes(path, text.data(), text.size()); }

std::string writeHeightMap(const std::string& path, int w, int h, const std::function<double(double, double)>& f) {
  std::vector<float> px(size_t(w) * size_t(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) px[size_t(y) * size_t(w) + size_t(x)] = float(f((x + 0.5) / w, 1.0 - (y + 0.5) / h));
  auto out = OIIO::ImageOutput::create(path);
  EXPECT_TRUE(out && out->open(path, OIIO::ImageSpec(w, h, 1, OIIO::TypeDesc::FLOAT))) << path;
  if (out) {
    EXPECT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data())) << path;
    out->close();
  }
  return path;
}

std::string writeRipples(const std::string& dir) {
  return writeHeightMap(dir + "/ripples.exr", 64, 4, [](double u, double) { return 0.5 + 0.5 * std::cos(4 * M_PI * u); });
}

ReadBack readExr(const std::string& path) {
  ReadBack r;
  auto in = OIIO::ImageInput::open(path);
  EXPECT_TRUE(in) << OIIO::geterror();
  if (!in) return r;
  r.spec = in->spec();
  std::vector<float> px(size_t(r.spec.width) * r.spec.height * r.spec.nchannels);
  r.ok = in->read_image(0, 0, 0, r.spec.nchannels, OIIO::TypeDesc::FLOAT, px.data());
  EXPECT_TRUE(r.ok);
  for (int c = 0; c < r.spec.nchannels; ++c) {
    auto& plane = r.planes[r.spec.channelnames[size_t(c)]];
    plane.resize(size_t(r.spec.width) * r.spec.height);
    for (size_t i = 0; i < plane.size(); ++i) plane[i] = px[i * size_t(r.spec.nchannels) + size_t(c)];
  }
  return r;
}

// --- warnings -----------------------------------------------------------------

WarningCapture::WarningCapture() {
  Log::resetOnce();
  Log::setWarningSink([this](const std::string& m) { messages.push_back(m); });
}

WarningCapture::~WarningCapture() { Log::setWarningSink(nullptr); }

size_t WarningCapture::count(const std::string& needle) const {
  size_t n = 0;
  for (const auto& m : messages) n += m.find(needle) != std::string::npos ? 1 : 0;
  return n;
}

std::string WarningCapture::all() const {
  std::string s;
  for (const auto& m : messages) s += "  [" + m + "]\n";
  return s;
}

// --- the CLI ------------------------------------------------------------------

// Starts the binary; returns its pid, or -1 with the reason in r.stderrText.
pid_t startCli(const std::vector<std::string>& args, const std::string& stderrPath, CliResult& r) {
  std::vector<std::string> all = {OBSCURA_BINARY};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 2, stderrPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, OBSCURA_BINARY, &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    r.stderrText = "posix_spawn failed: " + std::string(std::strerror(rc));
    return -1;
  }
  return pid;
}

// Waits for a started process; fills in how it ended and what it wrote.
void finishCli(pid_t pid, const std::string& stderrPath, CliResult& r) {
  if (pid < 0) return;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status)) r.exitCode = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  const auto bytes = readBytes(stderrPath);
  r.stderrText.assign(bytes.begin(), bytes.end());
}

CliResult runCli(const std::vector<std::string>& args, const std::string& stderrPath) {
  CliResult r;
  finishCli(startCli(args, stderrPath, r), stderrPath, r);
  return r;
}

std::vector<CliResult> runClis(const std::vector<std::vector<std::string>>& argLists, const std::string& dir) {
  std::vector<CliResult> results(argLists.size());
  std::vector<pid_t> pids(argLists.size(), -1);
  const auto errPath = [&](size_t i) { return dir + "/stderr" + std::to_string(i) + ".txt"; };
  const size_t width = std::max(2u, std::thread::hardware_concurrency());
  for (size_t begin = 0; begin < argLists.size(); begin += width) {
    const size_t end = std::min(argLists.size(), begin + width);
    for (size_t i = begin; i < end; ++i) pids[i] = startCli(argLists[i], errPath(i), results[i]);
    for (size_t i = begin; i < end; ++i) finishCli(pids[i], errPath(i), results[i]);
  }
  return results;
}

}  // namespace obscura::test
