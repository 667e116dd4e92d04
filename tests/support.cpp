#include "tests/support.h"
#include "tests/limited_cli.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
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

#include <obscura/error.h>
#include "core/image/texture.h"

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
  return env && *env ? std::string(env) : std::string(defaultScenesDir());
}

std::string sharedScene(const std::string& rel) { return sharedScenesDir() + "/" + rel; }

bool sharedScenesRequired() {
  const char* env = std::getenv("OBSCURA_REQUIRE_SCENES");
  return env && *env && std::string(env) != "0";
}

bool clientsRequired() {
  const char* ci = std::getenv("CI");
  return sharedScenesRequired() || (ci && std::string(ci) == "true");
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
  // alpha = 0 closes the sphere: ring 0 is then the +Z pole, one vertex.
  const bool closed = alpha <= 0.0;
  const auto ringSize = [&](int r) { return r == rings || (closed && r == 0) ? 1 : segments; };
  // Ring r at polar angle theta_r from +Z: theta_0 = alpha (hole edge) to
  // theta_rings = pi (the -Z pole, one vertex).
  std::vector<uint32_t> first(size_t(rings) + 1);
  for (int r = 0; r <= rings; ++r) {
    first[size_t(r)] = uint32_t(pos.size());
    const double theta = alpha + (M_PI - alpha) * double(r) / rings;
    for (int s = 0; s < ringSize(r); ++s) {
      const double phi = 2.0 * M_PI * double(s) / segments;
      const Vec3 p(float(rs * std::sin(theta) * std::cos(phi)), float(rs * std::sin(theta) * std::sin(phi)),
                   float(rs * std::cos(theta)));
      const bool pole = ringSize(r) == 1;
      const Vec3 polePos(0, 0, r == rings ? -rs : rs);
      pos.push_back(pole ? polePos : p);
      nrm.push_back(pole ? normalize(-polePos) : normalize(-p));
    }
  }
  const auto at = [&](int r, int s) {
    return ringSize(r) == 1 ? first[size_t(r)] : first[size_t(r)] + uint32_t(s % segments);
  };
  for (int r = 0; r + 1 < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      idx.insert(idx.end(), {at(r, s), at(r + 1, s), at(r + 1, s + 1)});
      if (ringSize(r) > 1) idx.insert(idx.end(), {at(r, s), at(r + 1, s + 1), at(r, s + 1)});
    }
  for (int s = 0; s < segments; ++s) idx.insert(idx.end(), {at(rings - 1, s), at(rings, 0), at(rings - 1, s + 1)});
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

RayHit traceClosest(const Scene& scene, Vec3 org, Vec3 dir) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RayHit rh{};
  rh.ray.org_x = org.x, rh.ray.org_y = org.y, rh.ray.org_z = org.z;
  rh.ray.dir_x = dir.x, rh.ray.dir_y = dir.y, rh.ray.dir_z = dir.z;
  rh.ray.tfar = kInfinity;
  rh.ray.mask = ~0u;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene.rtcScene(), &ctx, Tracer::embree(&rh));
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

std::unique_ptr<Integrator> makeIntegrator(const std::string& name, const std::vector<std::string>& params) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find(name);
  ParamSet p(d.params, d.name);
  for (const auto& a : params) p.setAssignment(a);
  return d.create(p);
}

Film renderWith(const Scene& scene, const Camera& camera, const std::string& integrator,
                const std::vector<std::string>& params, const RenderSettings& settings, RenderStats* stats) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find(integrator);
  ParamSet p(d.params, d.name);
  for (const auto& a : params) p.setAssignment(a);
  auto integ = d.create(p);
  RenderStats local;
  return render(scene, camera, *integ, passNeeds(d, p), settings, stats ? *stats : local);
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

PixelStats pixelStats(const Film& film, int c) {
  std::vector<double> v;
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x)
      if (film.at(kA, x, y) == 1.0f) v.push_back(film.at(c, x, y));
  PixelStats s;
  s.n = v.size();
  if (s.n < 2) return s;
  for (double x : v) s.mean += x;
  s.mean /= double(s.n);
  double m2 = 0, m4 = 0;
  for (double x : v) {
    const double d = (x - s.mean) * (x - s.mean);
    m2 += d, m4 += d * d;
  }
  s.sd = std::sqrt(m2 / double(s.n - 1));
  s.se = s.sd / std::sqrt(double(s.n));
  m2 /= double(s.n), m4 /= double(s.n);
  s.kurtosis = m2 > 0 ? m4 / (m2 * m2) : 0;
  return s;
}

void expectSameFilm(const Film& a, const Film& b, const std::string& what) {
  ASSERT_EQ(a.channels().size(), b.channels().size()) << what;
  ASSERT_EQ(a.width(), b.width()) << what;
  ASSERT_EQ(a.height(), b.height()) << what;
  ASSERT_EQ(a.originX(), b.originX()) << what;
  ASSERT_EQ(a.originY(), b.originY()) << what;
  const size_t n = size_t(a.width()) * size_t(a.height());
  for (size_t k = 0; k < a.channels().size(); ++k) {
    const int c = a.channels()[k];
    ASSERT_EQ(a.name(c), b.name(b.channels()[k])) << what;
    ASSERT_EQ(std::memcmp(a.plane(c), b.plane(b.channels()[k]), n * sizeof(float)), 0) << what << ": " << a.name(c);
  }
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

// --- screen-space passes ------------------------------------------------------

MeanSe meanSe(const std::vector<double>& v) {
  MeanSe m;
  m.n = v.size();
  if (v.empty()) return m;
  for (double x : v) m.mean += x;
  m.mean /= double(v.size());
  double var = 0;
  for (double x : v) var += (x - m.mean) * (x - m.mean);
  var /= std::max<double>(1.0, double(v.size()) - 1.0);
  m.se = std::sqrt(var / double(v.size()));
  return m;
}

MeanSe replicateMean(int replicates, const std::function<double(uint32_t seed)>& stat) {
  std::vector<double> v;
  for (int r = 1; r <= replicates; ++r) v.push_back(stat(uint32_t(r)));
  return meanSe(v);
}

std::vector<double> coveredW(const Film& f, int border) {
  std::vector<double> v;
  for (int y = border; y < f.height() - border; ++y)
    for (int x = border; x < f.width() - border; ++x)
      if (f.at(kA, x, y) == 1.0f) v.push_back(f.at(kR, x, y));
  return v;
}

Crease::Crease() : cam(makeLookAtCamera(Vec3(3.5f, -2.5f, 3.0f), Vec3(0.2f, 0, 0.1f), Vec3(0, 0, 1), 0.7f, "crease")) {
  scene.addWorldPrimitive({{0, -10, 0}, {10, -10, 0}, {10, 10, 0}, {0, 10, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene.addWorldPrimitive({{0, -10, 0}, {0, 10, 0}, {0, 10, 10}, {0, -10, 10}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene.commit();
}

bool Crease::floorAtFilm(int w, int h, float fx, float fy, Vec3& p) const {
  const RasterCamera rc(cam, w, h);
  const Vec3 d = rc.direction(fx, fy);
  const RayHit hit = traceClosest(scene, rc.org, d);
  if (hit.hit.geomID != 0) return false;
  p = rc.org + d * hit.ray.tfar;
  return true;
}

double creaseVo(double h, double R) {
  const double eta = std::min(h / R, 1.0);
  return (2.0 + 3.0 * eta - eta * eta * eta) / 4.0;
}

double creaseCosine(double h, double R) {
  const double eta = std::min(h / R, 1.0);
  return 1.0 - (std::acos(eta) - eta * std::sqrt(1.0 - eta * eta)) / 3.14159265358979323846;
}

CreaseCentres creaseCentres(const Crease& c, int w, int h, double R, double (*closedForm)(double, double),
                            double slope) {
  CreaseCentres out;
  for (int y = 1; y + 1 < h; ++y)
    for (int x = 1; x + 1 < w; ++x) {
      Vec3 p, px, py;
      if (!c.floorAt(w, h, x, y, p) || !c.floorAt(w, h, x + 1, y, px) || !c.floorAt(w, h, x, y + 1, py) ||
          p.x > 1.5 * R || std::abs(p.y) > 1.0f)
        continue;
      out.pixels.emplace_back(x, y);
      out.V.push_back(closedForm(p.x, R));
      out.footprint += slope / R * (std::abs(px.x - p.x) + std::abs(py.x - p.x)) / 2.0;
    }
  out.footprint /= double(std::max<size_t>(1, out.pixels.size()));
  return out;
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

namespace {
// Writes w x h texels of `channels` channels of `type` from `px`.
void writeImage(const std::string& path, int w, int h, int channels, OIIO::TypeDesc type, const void* px) {
  auto out = OIIO::ImageOutput::create(path);
  EXPECT_TRUE(out && out->open(path, OIIO::ImageSpec(w, h, channels, type))) << path;
  if (out) {
    EXPECT_TRUE(out->write_image(type, px)) << path;
    out->close();
  }
}
}  // namespace

std::string writeHeightMap(const std::string& path, int w, int h, const std::function<double(double, double)>& f) {
  std::vector<float> px(size_t(w) * size_t(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) px[size_t(y) * size_t(w) + size_t(x)] = float(f((x + 0.5) / w, 1.0 - (y + 0.5) / h));
  writeImage(path, w, h, 1, OIIO::TypeDesc::FLOAT, px.data());
  return path;
}

std::string writeRgbTexture(const std::string& path, int w, int h, const std::function<Vec3(double, double)>& f) {
  std::vector<uint16_t> px(size_t(w) * size_t(h) * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Vec3 c = f((x + 0.5) / w, 1.0 - (y + 0.5) / h);
      for (int k = 0; k < 3; ++k)
        px[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(k)] =
            uint16_t(std::lround(std::clamp(c[k], 0.0f, 1.0f) * 65535));
    }
  writeImage(path, w, h, 3, OIIO::TypeDesc::UINT16, px.data());
  return path;
}

double cornerFormFactor(double X, double Y, double h) {
  const double A = X / h, B = Y / h;
  const double sa = std::sqrt(1 + A * A), sb = std::sqrt(1 + B * B);
  return (A / sa * std::atan(B / sa) + B / sb * std::atan(A / sb)) / (2 * M_PI);
}

double rectFormFactor(double x0, double x1, double y0, double y1, double h, double px, double py) {
  x0 -= px, x1 -= px, y0 -= py, y1 -= py;
  return cornerFormFactor(x1, y1, h) - cornerFormFactor(x0, y1, h) - cornerFormFactor(x1, y0, h) +
         cornerFormFactor(x0, y0, h);
}

std::string writeAlphaTexture(const std::string& path, int w, int h, const std::function<double(int, int)>& alpha) {
  std::vector<uint8_t> px(size_t(w) * size_t(h) * 4, 255);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      px[(size_t(y) * size_t(w) + size_t(x)) * 4 + 3] = uint8_t(std::lround(std::clamp(alpha(x, y), 0.0, 1.0) * 255));
  writeImage(path, w, h, 4, OIIO::TypeDesc::UINT8, px.data());
  return path;
}

int addTexturedMaterial(Scene& scene, const std::string& path) {
  scene.textures.push_back(std::make_unique<Texture>(readBytes(path), path, false));
  Material m;
  m.name = "textured";
  m.texture = int(scene.textures.size()) - 1;
  scene.materials.push_back(m);
  return int(scene.materials.size()) - 1;
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
  std::vector<std::string> all = {obscuraBinary()};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 2, stderrPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, obscuraBinary(), &fa, nullptr, argv.data(), environ);
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

LimitedCliResult runCliLimited(const std::vector<std::string>& args, const std::string& stderrPath,
                               uint64_t addressSpaceBytes) {
  LimitedCliResult r;
#ifdef __SANITIZE_ADDRESS__
  // AddressSanitizer reserves terabytes of shadow address space as the
  // program starts, so no RLIMIT_AS a test can set lets an ASan build
  // start. There the limit is left off: the refusal and its one line are
  // still asserted, and the Release run asserts it comes before the
  // allocation.
  addressSpaceBytes = 0;
#endif
  // Everything the child needs is made before the fork: the child of a
  // threaded process may not allocate.
  std::vector<std::string> all = {obscuraBinary()};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  const rlimit lim{rlim_t(addressSpaceBytes), rlim_t(addressSpaceBytes)};
  const pid_t pid = fork();
  if (pid < 0) {
    r.stderrText = std::string("fork failed: ") + std::strerror(errno);
    return r;
  }
  if (pid == 0) {
    // The child: only async-signal-safe calls until exec.
    const int out = open("/dev/null", O_WRONLY), err = open(stderrPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (out < 0 || err < 0 || dup2(out, 1) < 0 || dup2(err, 2) < 0) _exit(127);
    if (addressSpaceBytes > 0 && setrlimit(RLIMIT_AS, &lim) != 0) _exit(127);
    execv(obscuraBinary(), argv.data());
    _exit(127);
  }
  int status = 0;
  rusage ru{};
  while (wait4(pid, &status, 0, &ru) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status)) r.exitCode = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  r.peakRssBytes = uint64_t(ru.ru_maxrss) * 1024;  // ru_maxrss is in KiB on Linux
  const auto bytes = readBytes(stderrPath);
  r.stderrText.assign(bytes.begin(), bytes.end());
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
