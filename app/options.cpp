#include "app/options.h"

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "core/render/adaptive.h"
#include <obscura/error.h>
#include <obscura/params.h>
#include "core/render/plugin_loader.h"
#include <obscura/plugin.h>
#include "core/util/memory_budget.h"
#include "core/util/option_names.h"

namespace obscura {

PixelRect parseRegion(const std::string& s) {
  PixelRect r;
  int* v[4] = {&r.x0, &r.y0, &r.x1, &r.y1};
  size_t pos = 0;
  for (int i = 0; i < 4; ++i) {
    const size_t end = i < 3 ? s.find(',', pos) : s.size();
    const std::string part = end == std::string::npos ? "" : s.substr(pos, end - pos);
    char* stop = nullptr;
    errno = 0;
    const long x = part.empty() ? 0 : std::strtol(part.c_str(), &stop, 10);
    if (part.empty() || *stop != '\0' || errno != 0 || x < 0 || x > 65536)
      throw Error("--region " + s + ": expected X0,Y0,X1,Y1 (four pixel coordinates in [0, 65536])");
    *v[i] = int(x);
    pos = end + 1;
  }
  return r;
}

void parseResolution(const std::string& s, int& w, int& h) {
  const size_t x = s.find('x');
  const auto num = [&](const std::string& t) -> int {
    if (t.empty() || t.size() > 6 || t.find_first_not_of("0123456789") != std::string::npos) return -1;
    return std::atoi(t.c_str());
  };
  w = x == std::string::npos ? -1 : num(s.substr(0, x));
  h = x == std::string::npos ? -1 : num(s.substr(x + 1));
  if (w < 1 || h < 1 || w > 65536 || h > 65536)
    throw Error("--res: expected WIDTHxHEIGHT with each in [1, 65536], got '" + s + "'");
}

std::shared_ptr<const Environment> loadEnvironment(const EnvironmentArgs& a, const std::string& sky) {
  const bool other = a.rotation != 0.0 || a.strength != 1.0 || a.irradiance != "exact";
  if (a.environment.empty()) {
    if (other)
      throw Error("--environment-rotation, --environment-strength and --environment-irradiance need --environment");
    return nullptr;
  }
  if (sky != "1,1,1")
    throw Error("--sky and --environment: give one (--sky is the uniform environment; scale a map with "
                "--environment-strength)");
  if (!std::isfinite(a.rotation))
    throw Error("--environment-rotation: expected finite degrees, got " + formatFloat(a.rotation));
  if (!(a.strength >= 0.0) || !std::isfinite(a.strength) || a.strength > 1e30)
    throw Error("--environment-strength: expected a value in [0, 1e30], got " + formatFloat(a.strength));
  EnvironmentOptions o;
  o.path = a.environment;
  o.rotationDegrees = a.rotation;
  o.strength = a.strength;
  o.irradiance = irradianceMethodFromName(a.irradiance, "--environment-irradiance");
  return Environment::load(o);
}

std::string describeEnvironment(const Environment& e) {
  const EnvironmentOptions& o = e.options();
  const Vec3 m = e.meanRadiance();
  char text[512];
  std::snprintf(text, sizeof text,
                "environment %s  %ux%u texels  rotation %s deg  strength %s  content %s\n"
                "           mean radiance (%.6g, %.6g, %.6g)%s\n"
                "           E0 by %s; SH9 against the exact table: max %.3g%%, rms %.3g%% of the mean E0\n",
                o.path.c_str(), e.width(), e.height(), formatFloat(o.rotationDegrees).c_str(),
                formatFloat(o.strength).c_str(), e.contentHash().c_str(), m.x, m.y, m.z,
                e.isConstant() ? "  (constant: the uniform sky)" : "", irradianceMethodName(o.irradiance),
                100.0 * e.sh9Error().max, 100.0 * e.sh9Error().rms);
  return text;
}

Vec3 parseSky(const std::string& s) {
  std::vector<float> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const float f = std::strtof(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !std::isfinite(f) || f < 0)
      throw Error("--sky: expected R,G,B (finite, non-negative), got '" + s + "'");
    v.push_back(f);
  }
  if (v.size() == 1) v = {v[0], v[0], v[0]};
  if (v.size() != 3) throw Error("--sky: expected R,G,B (finite, non-negative), got '" + s + "'");
  return {v[0], v[1], v[2]};
}

void checkThreads(long long threads) {
  if (threads < 0) throw Error("--threads: must be >= 0 (0 = all cores), got " + std::to_string(threads));
  if (threads > kMaxThreads)
    throw Error("--threads: at most " + std::to_string(kMaxThreads) + " (0 = all cores), got " + std::to_string(threads));
}

Camera selectCamera(const Scene& scene, const std::string& want, float aspect) {
  const auto autoCamera = [&] {
    // Far from a scene near the coordinate limit, or framing it through a
    // very narrow image, the camera could leave the range Embree traces.
    const std::string what = scene.sourcePath + ": the automatic camera (--camera auto)";
    Camera c = makeAutoCamera(scene.bounds(), aspect);
    // A scene of no size (one point: equal vertices, a node scaled by 0 or
    // 1e-25, a small mesh so far out its coordinates collapse to one float)
    // leaves the camera no distance to stand back: its eye equals the
    // centre, or their difference underflows, and the look-at frame is NaN.
    const Vec3 eye = c.position(), centre = scene.bounds().center();
    const bool inRange = inTraceableRange(eye.x) && inTraceableRange(eye.y) && inTraceableRange(eye.z);
    if (inRange && (!cameraFrameValid(c.toWorld) ||
        (!scene.bounds().empty() && eye.x == centre.x && eye.y == centre.y && eye.z == centre.z)))
      throw Error(what + ": the scene's bounds have no extent to frame; give the scene a camera");
    checkCameraRange(c, what);
    return c;
  };
  // A file's camera is checked on load; checked again here (cheaply) so no
  // primary ray with a NaN or infinite origin or direction reaches Embree.
  const auto checked = [&](const Camera& c) {
    checkCameraRange(c, scene.sourcePath + ": camera '" + c.name + "'");
    return c;
  };
  if (want.empty()) return scene.cameras.empty() ? autoCamera() : checked(scene.cameras[0]);
  if (want == "auto") return autoCamera();
  std::string names;
  for (const auto& c : scene.cameras) {
    if (c.name == want) return checked(c);
    names += (names.empty() ? "" : ", ") + c.name;
  }
  if (want.find_first_not_of("0123456789") == std::string::npos && want.size() < 9) {
    const int i = std::stoi(want);
    for (const auto& c : scene.cameras)
      if (c.fileIndex == i) return checked(c);
    throw Error("--camera: no perspective camera with index " + want + " (the scene has " +
                std::to_string(scene.cameras.size()) + " usable camera" + (scene.cameras.size() == 1 ? "" : "s") + ")");
  }
  throw Error("--camera: no camera named '" + want + "' (cameras: " + (names.empty() ? "none" : names) +
              "; or 'auto')");
}


void nameSettingsAsFlags() {
  setSettingName(Setting::Spp, "--spp");
  setSettingName(Setting::MaxMemory, "--max-memory");
  setSettingName(Setting::Subdivision, "--subdiv");
  setSettingName(Setting::SubdivisionBackendOsd, "--subdiv-backend osd");
  setSettingName(Setting::Displacement, "--displace");
  setSettingName(Setting::DisplacementScale, "--displace-scale");
  setSettingName(Setting::Time, "--frame");
  setSettingName(Setting::Animations, "--animation");
  setSettingName(Setting::Shutter, "--shutter");
  setSettingName(Setting::TargetError, "--target-error");
  setSettingName(Setting::MinSpp, "--min-spp");
  setSettingName(Setting::TimeLimit, "--time-limit");
  setSettingName(Setting::BackgroundSpp, "--background-spp");
}

void loadPlugins(const std::vector<std::string>& paths) {
  loadPluginsFromEnvironment();
  for (const auto& p : paths) loadPlugin(p);
}

LoadOptions sceneOptions(const SceneArgs& a) {
  LoadOptions o;
  o.robust = a.robust;
  if (a.normalMaps != "on" && a.normalMaps != "off")
    throw Error("--normal-maps: expected on or off, got '" + a.normalMaps + "'");
  o.normalMaps = a.normalMaps == "on";
  if (a.subdiv == "catmull-clark") o.subdivision = true, o.scheme = SubdivisionScheme::CatmullClark;
  else if (a.subdiv == "loop") o.subdivision = true, o.scheme = SubdivisionScheme::Loop;
  else if (a.subdiv != "none") throw Error("--subdiv: expected none, catmull-clark or loop, got '" + a.subdiv + "'");
  if (a.subdivLevel < 0 || a.subdivLevel > 10)
    throw Error("--subdiv-level: must be in [0, 10], got " + std::to_string(a.subdivLevel));
  if (!(a.maxMemoryGiB > 0) || !std::isfinite(a.maxMemoryGiB) || a.maxMemoryGiB > 1e6)
    throw Error("--max-memory: expected a positive number of GiB");
  o.subdivisionLevel = a.subdivLevel;
  if (a.subdivBackend == "osd") o.backend = SubdivisionBackend::OpenSubdiv;
  else if (a.subdivBackend == "embree") o.backend = SubdivisionBackend::Embree;
  else throw Error("--subdiv-backend: expected osd or embree, got '" + a.subdivBackend + "'");
  if (!(a.subdivEdge >= 0) || !std::isfinite(a.subdivEdge))
    throw Error("--subdiv-edge: expected a non-negative number of pixels");
  if (a.subdivEdge > 0 && a.subdivEdge < 0.05) throw Error("--subdiv-edge: below 0.05 pixels (use a larger value)");
  o.maxEdgePixels = a.subdivEdge;
  if (!std::isfinite(a.displaceScale)) throw Error("--displace-scale: must be finite");
  if (!std::isfinite(a.displaceMidlevel)) throw Error("--displace-midlevel: must be finite");
  o.displacementMap = a.displace;
  o.displacementScale = a.displaceScale;
  o.displacementMidlevel = a.displaceMidlevel;
  o.maxMemoryBytes = size_t(a.maxMemoryGiB * double(size_t(1) << 30));
  // The budget of the whole process (core/util/memory_budget.h): images
  // read outside the scene (references, maps, tiles) are held to it too.
  setMemoryBudget(o.maxMemoryBytes);
  for (const std::string& text : a.objects) o.objectOverrides.push_back(parseObjectOverride(text));
  if (!(a.fps > 0) || !std::isfinite(a.fps) || a.fps > 1e6)
    throw Error("--fps: expected a positive number of frames per second (at most 1e6), got " + formatFloat(a.fps));
  if (!a.frame.empty()) o.time = parseFrame(a.frame) / a.fps;
  else if (!a.animations.empty())
    throw Error("--animation: selects the animations a frame plays; give --frame (or, for render, --frames)");
  for (const std::string& name : a.animations)
    if (name.empty()) throw Error("--animation: an empty name in the list");
  o.animations = a.animations;
  if (!a.shutter.empty()) {
    const std::array<double, 2> sh = parseShutter(a.shutter);
    if (a.frame.empty()) throw Error("--shutter: motion blur opens the shutter around a frame; give --frame (or, for render, --frames)");
    const double f = parseFrame(a.frame);
    o.shutter = std::array<double, 2>{(f + sh[0]) / a.fps, (f + sh[1]) / a.fps};
  }
  return o;
}

std::array<double, 2> parseShutter(const std::string& text) {
  const std::string why = "--shutter: expected OPEN,CLOSE in frames relative to the frame, OPEN < CLOSE "
                          "(e.g. -0.25,0.25 for a 180-degree shutter centred on the frame), got '" + text + "'";
  const size_t comma = text.find(',');
  if (comma == std::string::npos || text.find(',', comma + 1) != std::string::npos) throw Error(why);
  std::array<double, 2> v{};
  for (int k = 0; k < 2; ++k) {
    const std::string part = k == 0 ? text.substr(0, comma) : text.substr(comma + 1);
    char* end = nullptr;
    errno = 0;
    v[size_t(k)] = std::strtod(part.c_str(), &end);
    if (part.empty() || *end != '\0' || errno != 0 || !std::isfinite(v[size_t(k)]) || std::abs(v[size_t(k)]) > 1e6 ||
        part.find_first_of("xXpPnN") != std::string::npos)
      throw Error(why);
  }
  if (!(v[0] < v[1])) throw Error(why);
  return v;
}

double parseFrame(const std::string& text) {
  char* end = nullptr;
  errno = 0;
  const double f = std::strtod(text.c_str(), &end);
  // Frames past 1e15 lose whole-frame resolution in a double's seconds.
  if (text.empty() || *end != '\0' || errno != 0 || !std::isfinite(f) || std::abs(f) > 1e15 ||
      text.find_first_of("xXpPnN") != std::string::npos)  // no hex floats, nan, inf
    throw Error("--frame: expected a frame number (e.g. 12 or 12.5), got '" + text + "'");
  return f;
}

std::vector<long long> parseFrameRange(const std::string& text) {
  const std::string why = "--frames: expected A-B[:STEP] (whole frames A <= B, STEP >= 1), got '" + text + "'";
  // A whole number at `pos` (an optional '-' then digits); advances pos.
  const auto integer = [&](size_t& pos) -> long long {
    const size_t start = pos;
    if (pos < text.size() && text[pos] == '-') ++pos;
    const size_t digits = pos;
    while (pos < text.size() && std::isdigit(static_cast<unsigned char>(text[pos]))) ++pos;
    if (pos == digits || pos - digits > 9) throw Error(why);
    return std::stoll(text.substr(start, pos - start));
  };
  size_t pos = 0;
  const long long a = integer(pos);
  if (pos >= text.size() || text[pos] != '-') throw Error(why);
  ++pos;
  const long long b = integer(pos);
  long long step = 1;
  if (pos < text.size()) {
    if (text[pos] != ':') throw Error(why);
    ++pos;
    const size_t s0 = pos;
    step = integer(pos);
    if (text[s0] == '-' || step < 1) throw Error(why);
  }
  if (pos != text.size() || a > b) throw Error(why);
  if ((b - a) / step >= 1000000) throw Error("--frames '" + text + "': more than a million frames");
  std::vector<long long> out;
  for (long long f = a; f <= b; f += step) out.push_back(f);
  return out;
}

FramePattern framePattern(const std::string& option, const std::string& path) {
  const size_t slash = path.find_last_of('/');
  const size_t nameStart = slash == std::string::npos ? 0 : slash + 1;
  FramePattern p;
  const size_t first = path.find('#', nameStart);
  if (first == std::string::npos) return p;
  size_t end = first;
  while (end < path.size() && path[end] == '#') ++end;
  if (path.find('#', end) != std::string::npos)
    throw Error(option + " " + path + ": more than one run of '#' (the frame number goes in one run, e.g. out.####.exr)");
  p.pos = first, p.length = end - first;
  return p;
}

std::string frameFileName(const std::string& path, const FramePattern& p, long long frame) {
  char digits[32];
  std::snprintf(digits, sizeof digits, "%0*lld", int(p.length), frame);
  return path.substr(0, p.pos) + digits + path.substr(p.pos + p.length);
}

std::unique_ptr<Scene> loadSceneAndCamera(const SceneArgs& a, const std::string& path, const std::string& want, int width,
                                          int height, Camera& camera) {
  sceneOptions(a);  // the options are checked before the file is read
  const SceneSource source(path);  // parsed once, built at most twice
  return loadSceneAndCamera(a, source, want, width, height, camera);
}

std::unique_ptr<Scene> loadSceneAndCamera(const SceneArgs& a, const SceneSource& source, const std::string& want, int width,
                                          int height, Camera& camera) {
  LoadOptions o = sceneOptions(a);
  const float aspect = float(width) / float(height);
  if (o.maxEdgePixels > 0) {
    LoadOptions probe = o;
    probe.subdivision = false;
    probe.unrefined = true;
    probe.maxEdgePixels = 0;
    probe.displacementMap.clear();
    probe.backend = SubdivisionBackend::OpenSubdiv;
    o.camera = selectCamera(*source.build(probe), want, aspect);
    o.imageWidth = width, o.imageHeight = height;
  }
  std::unique_ptr<Scene> scene = source.build(o);
  // The probe's camera measured the refinement. A file's camera is taken
  // again from the full build, which is the same camera plus what only the
  // full build gives it: its motion steps under --shutter. The automatic one
  // is kept, as it framed the probe (the refined bounds differ a little).
  camera = o.camera && o.camera->fileIndex < 0 ? *o.camera : selectCamera(*scene, want, aspect);
  return scene;
}

IntegratorSpec parseIntegratorSpec(const std::string& option, const std::string& text) {
  IntegratorSpec c;
  const std::string where = option + " '" + text + "': ";
  const size_t colon = text.find(':');
  c.integrator = text.substr(0, colon);
  if (c.integrator.empty()) throw Error(where + "expected integrator[:key=value,...]");
  const IntegratorDescriptor* desc = nullptr;
  try {
    desc = &IntegratorRegistry::instance().find(c.integrator);
  } catch (const Error& e) {
    throw Error(where + e.what());
  }
  ParamSet params(desc->params, desc->name);
  if (colon != std::string::npos) {
    std::stringstream ss(text.substr(colon + 1));
    std::string item;
    while (std::getline(ss, item, ',')) {
      if (item.empty() || item.find('=') == std::string::npos || item.front() == '=')
        throw Error(where + "expected key=value, got '" + item + "'");
      try {
        params.setAssignment(item);
      } catch (const Error& e) {
        throw Error(where + e.what());
      }
      c.assignments.push_back(item);
    }
    if (c.assignments.empty() || text.back() == ',') throw Error(where + "expected key=value after ':'");
  }
  c.canonical = c.integrator;
  for (const auto& [k, v] : params.values()) c.canonical += ":" + k + "=" + v;
  return c;
}

}  // namespace obscura
