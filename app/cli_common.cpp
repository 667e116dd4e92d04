#include "app/cli_common.h"

#include <tbb/task_arena.h>

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

Camera selectCamera(const Scene& scene, const std::string& want, float aspect) {
  const auto autoCamera = [&] {
    // Far from a scene near the coordinate limit, or framing it through a
    // very narrow image, the camera could leave the range Embree traces.
    Camera c = makeAutoCamera(scene.bounds(), aspect);
    checkCameraRange(c, scene.sourcePath + ": the automatic camera (--camera auto)");
    return c;
  };
  if (want.empty()) return scene.cameras.empty() ? autoCamera() : scene.cameras[0];
  if (want == "auto") return autoCamera();
  std::string names;
  for (const auto& c : scene.cameras) {
    if (c.name == want) return c;
    names += (names.empty() ? "" : ", ") + c.name;
  }
  if (want.find_first_not_of("0123456789") == std::string::npos && want.size() < 9) {
    const int i = std::stoi(want);
    for (const auto& c : scene.cameras)
      if (c.fileIndex == i) return c;
    throw Error("--camera: no perspective camera with index " + want + " (the scene has " +
                std::to_string(scene.cameras.size()) + " usable camera" + (scene.cameras.size() == 1 ? "" : "s") + ")");
  }
  throw Error("--camera: no camera named '" + want + "' (cameras: " + (names.empty() ? "none" : names) +
              "; or 'auto')");
}

// The camera in the OpenEXR standard attributes (ImfStandardAttributes.h),
// docs/exr.md "Depth and camera conventions". EXR/OpenImageIO matrices are
// row-vector form (p' = p M): the transpose of the column-vector matrices
// used in the code.
namespace {
using Mat4 = std::array<std::array<double, 4>, 4>;

// worldToCamera: OpenEXR's (and RenderMan's) camera space is left-handed,
// +X right, +Y up and +Z the viewing direction (points in front have z > 0).
// glTF's camera looks down its -Z, so the third axis is the negated one.
Mat4 worldToCamera(const Camera& c) {
  const Vec3 t = c.position();
  const Vec3 axes[3] = {c.toWorld.vector(Vec3(1, 0, 0)), c.toWorld.vector(Vec3(0, 1, 0)),
                        c.toWorld.vector(Vec3(0, 0, -1))};
  Mat4 m{};
  for (int r = 0; r < 3; ++r) {  // row-vector form: camera axis r is column r
    for (int k = 0; k < 3; ++k) m[size_t(k)][size_t(r)] = double(axes[r][k]);
    m[3][size_t(r)] = -(double(axes[r].x) * t.x + double(axes[r].y) * t.y + double(axes[r].z) * t.z);
  }
  m[3][3] = 1.0;
  return m;
}

// Camera space -> NDC (row-vector form), for an image of aspect w/h:
// NDC (0, 0) is the image's top-left corner and (1, 1) its bottom-right,
// after the divide by w = z; x_ndc = (x / (z tan(fovx/2)) + 1) / 2, y_ndc =
// (1 - y / (z tan(fovy/2))) / 2. The discarded z maps the clip range [n, f]
// to [0, 1] (f = far), as a perspective depth.
Mat4 cameraToNdc(const Camera& c, double aspect, double far) {
  const double ty = std::tan(0.5 * double(c.yfov)), tx = ty * aspect, n = double(c.znear);
  const double k = far > n ? far / (far - n) : 1.0;
  Mat4 p{};
  p[0][0] = 0.5 / tx;
  p[1][1] = -0.5 / ty;
  p[2][0] = 0.5, p[2][1] = 0.5, p[2][2] = k, p[2][3] = 1.0;
  p[3][2] = -k * n;
  return p;
}

std::vector<float> toAttribute(const Mat4& m) {
  std::vector<float> v;
  for (const auto& row : m)
    for (double x : row) v.push_back(float(x));
  return v;
}

Mat4 multiply(const Mat4& a, const Mat4& b) {
  Mat4 r{};
  for (size_t i = 0; i < 4; ++i)
    for (size_t j = 0; j < 4; ++j)
      for (size_t k = 0; k < 4; ++k) r[i][j] += a[i][k] * b[k][j];
  return r;
}

void addCameraAttributes(const Camera& c, int width, int height, bool aovs, std::vector<HeaderAttribute>& out) {
  const double aspect = double(width) / double(height);
  // No far clip (glTF's infinite projection): the background's depth, the
  // farthest Z the file holds.
  const double far = std::isfinite(c.zfar) ? double(c.zfar) : double(kBackgroundDepth);
  const Mat4 w2c = worldToCamera(c);
  out.push_back({"worldToCamera", toAttribute(w2c)});
  out.push_back({"worldToNDC", toAttribute(multiply(w2c, cameraToNdc(c, aspect, far)))});
  const double ty = std::tan(0.5 * double(c.yfov));
  const double degrees = 180.0 / 3.14159265358979323846;
  out.push_back({"obscura:fovHorizontal", float(2.0 * std::atan(ty * aspect) * degrees)});
  out.push_back({"obscura:fovVertical", float(double(c.yfov) * degrees)});
  // Obscura clips along each camera ray (glTF znear/zfar as distances).
  out.push_back({"obscura:clipNear", c.znear});
  out.push_back({"obscura:clipFar", float(far)});
  out.push_back({"obscura:upAxis", std::string("+Y")});
  if (!aovs) return;
  out.push_back({"obscura:N", std::string("world-space unit shading normal; world right-handed, +Y up (glTF)")});
  out.push_back({"obscura:Z", std::string("camera-plane depth: distance along the view axis (mean over the pixel's hits)")});
  out.push_back({"obscura:backgroundZ", kBackgroundDepth});
}

}  // namespace

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

ExrOptions passHeader(const PassInfo& i) {
  ExrOptions exr;
  const auto str = [&](const std::string& k, const std::string& v) { exr.attributes.push_back({k, v}); };
  str("Software", std::string("Obscura ") + OBSCURA_VERSION);
  str("obscura:version", OBSCURA_VERSION);
  str("obscura:scene", std::filesystem::absolute(i.scenePath).lexically_normal().string());
  str("obscura:camera", i.camera.name);
  str("obscura:integrator", i.integrator.name);
  std::string all;
  for (const auto& [k, v] : i.params.values()) {
    str("obscura:param:" + k, v);
    all += (all.empty() ? "" : ",") + k + "=" + v;
  }
  str("obscura:params", all);
  if (!i.layers.empty()) {
    // Each pass under its layer's name (docs/production.md "Several passes in one
    // render"); the unprefixed integrator and params above are the primary's.
    std::string list;
    for (const LayerInfo& l : i.layers) {
      const std::string key = "obscura:pass:" + l.layer + ":";
      str(key + "integrator", l.integrator->name);
      std::string ps;
      for (const auto& [k, v] : l.params->values()) {
        str(key + "param:" + k, v);
        ps += (ps.empty() ? "" : ",") + k + "=" + v;
      }
      str(key + "params", ps);
      list += (list.empty() ? "" : " ") + l.layer + "=" + l.integrator->name + (ps.empty() ? "" : ":" + ps);
    }
    str("obscura:passes", list);
    str("obscura:primaryPass", i.layers.front().layer);
  }
  // Sample counts are integers up to 2^24: half holds them exactly only to
  // 2048, so the spp plane stays float under --half (like N and Z).
  exr.floatChannelPrefixes.push_back(kSppPlane);
  exr.attributes.push_back({"obscura:spp", i.settings.spp});
  if (adaptiveSampling(i.settings)) {
    // docs/sampling.md "Adaptive sampling": the settings, and what they took.
    exr.attributes.push_back({"obscura:targetError", i.settings.targetError});
    exr.attributes.push_back({"obscura:minSpp", firstRoundSpp(i.settings)});
    exr.attributes.push_back({"obscura:backgroundSpp", i.stats.backgroundSpp});
    exr.attributes.push_back({"obscura:timeLimit", float(i.settings.timeLimit)});
    exr.attributes.push_back({"obscura:meanSpp", float(i.stats.meanSpp)});
    exr.attributes.push_back({"obscura:rounds", i.stats.rounds});
  }
  if (i.settings.denoise) {
    // docs/sampling.md "Denoising": the filter and its defaults (core/image/denoise.h).
    str("obscura:denoise", "atrous");
    exr.attributes.push_back({"obscura:denoiseTime", float(i.stats.denoiseSeconds)});
  }
  exr.attributes.push_back({"obscura:seed", int(i.settings.seed)});  // stored bit pattern; see README
  str("obscura:seedText", std::to_string(i.settings.seed));
  str("obscura:resolution", std::to_string(i.settings.width) + "x" + std::to_string(i.settings.height));
  {
    const PixelRect w = renderWindow(i.settings);  // --region, or the whole frame
    str("obscura:region", std::to_string(w.x0) + "," + std::to_string(w.y0) + "," + std::to_string(w.x1) + "," +
                              std::to_string(w.y1));
  }
  str("obscura:filter", i.filterName);
  exr.attributes.push_back({"obscura:robust", int(i.robust)});
  if (const SceneArgs* a = i.sceneArgs) {
    // What shaped the geometry: a pass is reproducible from its header.
    // Always: glTF meshes flagged in their extras are subdivided (by this
    // backend, level default and edge length) without --subdiv.
    str("obscura:subdiv", a->subdiv);
    str("obscura:subdivBackend", a->subdivBackend);
    exr.attributes.push_back({"obscura:subdivLevel", a->subdivLevel});
    exr.attributes.push_back({"obscura:subdivEdge", float(a->subdivEdge)});
    exr.attributes.push_back({"obscura:maxMemoryGiB", float(a->maxMemoryGiB)});
    if (!a->displace.empty()) {
      str("obscura:displace", std::filesystem::absolute(a->displace).lexically_normal().string());
      str("obscura:displaceScale", formatFloat(a->displaceScale));  // reads back as the same double
      str("obscura:displaceMidlevel", formatFloat(a->displaceMidlevel));
    }
  }
  if (const SceneArgs* a = i.sceneArgs; a && !a->frame.empty()) {
    // The frame and what it plays (docs/production.md "Animation and frames").
    const double frame = parseFrame(a->frame);
    str("obscura:frame", formatFloat(frame));
    str("obscura:fps", formatFloat(a->fps));
    str("obscura:time", formatFloat(frame / a->fps));
    std::string list;
    for (const std::string& n : a->animations) list += (list.empty() ? "" : ",") + n;
    str("obscura:animations", list.empty() ? "all" : list);
    if (!a->shutter.empty()) {
      // The shutter in frames relative to the frame, and what moves in it.
      const std::array<double, 2> sh = parseShutter(a->shutter);
      str("obscura:shutter", formatFloat(sh[0]) + "," + formatFloat(sh[1]));
      if (i.scene) exr.attributes.push_back({"obscura:movingObjects", int(i.scene->stats().movingInstances)});
    }
  }
  if (i.sceneArgs && !i.sceneArgs->objects.empty()) {
    std::string all;
    for (const std::string& o : i.sceneArgs->objects) all += (all.empty() ? "" : " ") + ("--object '" + o + "'");
    str("obscura:objectOverrides", all);
  }
  // Every object whose roles differ from the default, whoever set them (the
  // file's extras or --object): docs/production.md "Objects and roles".
  if (i.scene) str("obscura:objectRoles", nonDefaultRoles(i.scene->objects));
  str("obscura:sky", formatFloat(i.settings.sky.x) + "," + formatFloat(i.settings.sky.y) + "," + formatFloat(i.settings.sky.z));
  exr.attributes.push_back({"obscura:threads", i.settings.threads > 0 ? i.settings.threads : int(tbb::this_task_arena::max_concurrency())});
  exr.attributes.push_back({"obscura:renderTime", float(i.stats.seconds)});
  exr.attributes.push_back({"obscura:bvhBuildTime", float(i.bvhSeconds)});
  str("obscura:rays:camera", std::to_string(i.stats.rays.camera));
  str("obscura:rays:occlusion", std::to_string(i.stats.rays.occlusion));
  str("obscura:rays:closest", std::to_string(i.stats.rays.closest));
  str("obscura:rays:total", std::to_string(i.stats.rays.camera + i.stats.rays.occlusion + i.stats.rays.closest));
  addCameraAttributes(i.camera, i.settings.width, i.settings.height, i.settings.aovs, exr.attributes);
  if (i.scene && i.settings.cryptomatte.any()) addCryptomatteHeader(*i.scene, i.settings.cryptomatte, exr);
  return exr;
}

}  // namespace obscura
