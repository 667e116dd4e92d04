#include "app/exr_header.h"

#include <tbb/task_arena.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <string>

#include "core/render/adaptive.h"
#include <obscura/error.h>
#include <obscura/params.h>

namespace obscura {

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
    // Only when off, so the headers of renders that keep the default stay as they were.
    if (a->normalMaps != "on") str("obscura:normalMaps", a->normalMaps);
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
  if (const Environment* e = i.settings.environment.get(); e && !e->options().path.empty()) {
    // The map (docs/environment.md): its file, what it held (a hash of the
    // texels as read, so a re-encoded file with the same values matches),
    // how it was turned and scaled, and how E0 was computed.
    const EnvironmentOptions& o = e->options();
    str("obscura:environment", o.path);
    str("obscura:environmentHash", e->contentHash());
    str("obscura:environmentSize", std::to_string(e->width()) + "x" + std::to_string(e->height()));
    str("obscura:environmentRotation", formatFloat(o.rotationDegrees));
    str("obscura:environmentStrength", formatFloat(o.strength));
    str("obscura:environmentIrradiance", irradianceMethodName(o.irradiance));
    const Vec3 m = e->meanRadiance();
    str("obscura:environmentMeanRadiance", formatFloat(m.x) + "," + formatFloat(m.y) + "," + formatFloat(m.z));
  } else {
    str("obscura:sky", formatFloat(i.settings.sky.x) + "," + formatFloat(i.settings.sky.y) + "," + formatFloat(i.settings.sky.z));
  }
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
