// The options `render` and `compare` share: parsing them, loading the scene
// and selecting its camera, loading plugins, integrator specs. (The EXR
// header a pass carries: app/exr_header.h.)
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "core/scene/camera.h"
#include "core/scene/environment.h"
#include "core/load/gltf_loader.h"
#include "core/image/image_io.h"
#include "core/render/plugin_loader.h"
#include <obscura/integrator.h>
#include "core/render/render.h"
#include "core/scene/scene.h"

namespace obscura {

// "WIDTHxHEIGHT", each in [1, 65536]; throws obscura::Error naming --res.
void parseResolution(const std::string& s, int& w, int& h);
// "X0,Y0,X1,Y1" (--region, pixels, half-open); throws naming --region on a
// malformed text (core/render/render.h checkRegion checks it against the frame).
PixelRect parseRegion(const std::string& s);
// "R,G,B" or one value, finite and non-negative; throws naming --sky.
Vec3 parseSky(const std::string& s);

// The light of a render beyond the uniform --sky (docs/math.md §14): an
// equirectangular map, its rotation about the up axis and its strength,
// and how E0 is computed. Shared by render, compare, info and Python.
struct EnvironmentArgs {
  std::string environment;  // --environment FILE; empty: the uniform --sky
  double rotation = 0.0;    // --environment-rotation DEGREES
  double strength = 1.0;    // --environment-strength S
  std::string irradiance = "exact";  // --environment-irradiance exact|sh9
};
// The environment of `a` (null without --environment), checked and built:
// throws obscura::Error naming the option or the file. `sky` is --sky as
// typed: a sky other than the default beside --environment is refused.
std::shared_ptr<const Environment> loadEnvironment(const EnvironmentArgs& a, const std::string& sky);
// What `info` and a render print about an environment: its file, size,
// rotation and strength, mean radiance, and the SH9 fit's error against
// the exact E0 (lines of the form "environment ...\n").
std::string describeEnvironment(const Environment& e);
// The most worker threads --threads (and Python's threads=) accepts. TBB
// crashed (SIGSEGV) when its parallelism limit exceeded 65536 and reserves
// memory in proportion to it (2147483647 took all memory); no machine
// Obscura renders on has more than a few hundred cores, so 4096 refuses
// no real setting and stays far below both.
constexpr int kMaxThreads = 4096;
// Throws obscura::Error "--threads: ..." unless 0 <= threads <= kMaxThreads.
void checkThreads(long long threads);
// --camera: a name, an index into the file's cameras, "auto", or empty
// (the first camera, else auto).
Camera selectCamera(const Scene& scene, const std::string& want, float aspect);
// How scenes are loaded: the options `render` and `compare` share.
struct SceneArgs {
  bool robust = false;
  // --normal-maps on|off: glTF normalTexture bends the shading normal
  // (LoadOptions::normalMaps).
  std::string normalMaps = "on";
  std::string subdiv = "none";  // none | catmull-clark | loop (OBJ cages)
  std::string subdivBackend = "osd";  // osd | embree
  int subdivLevel = 2;
  double subdivEdge = 0;  // > 0: adaptive, max edge length in pixels
  double maxMemoryGiB = 8;
  std::string displace;  // height map
  double displaceScale = 0.1, displaceMidlevel = 0.5;
  std::vector<std::string> objects;  // --object GLOB:role=value,... (core/scene/objects.h)
  // Animation (docs/production.md "Animation and frames"): --frame as typed (empty: the
  // static pose), --fps, --animation's names or indices (empty: all).
  std::string frame;
  double fps = 24;
  std::vector<std::string> animations;
  // --shutter OPEN,CLOSE: motion blur over [frame + OPEN, frame + CLOSE]
  // (frames); empty = none (docs/production.md "Motion blur").
  std::string shutter;
};
// Checks them; throws obscura::Error naming the option.
LoadOptions sceneOptions(const SceneArgs& a);

// --frame's text as a number (fractional allowed, finite); throws naming --frame.
double parseFrame(const std::string& text);
// --shutter "OPEN,CLOSE": frames relative to the frame, OPEN < CLOSE, each
// finite and within +-1e6; throws naming --shutter.
std::array<double, 2> parseShutter(const std::string& text);
// --frames "A-B[:STEP]": whole frames A <= B (either may be negative), STEP >= 1.
std::vector<long long> parseFrameRange(const std::string& text);
// The run of '#' in the file name of `path` (an output pattern,
// out.####.exr): its position and length; length 0 when there is none.
// More than one run throws naming `option`.
struct FramePattern {
  size_t pos = 0, length = 0;
  bool any() const { return length > 0; }
};
FramePattern framePattern(const std::string& option, const std::string& path);
// `path` with the run replaced by `frame`, zero-padded to the run's length
// (the sign counts: -1 in #### is -001); longer numbers are not cut.
std::string frameFileName(const std::string& path, const FramePattern& p, long long frame);

// Loads `path` and selects its camera (--camera `want`) for a width x height
// image. Adaptive subdivision measures edges from that camera, so then the
// scene is first read with its cages unrefined (cheap) to find the camera.
std::unique_ptr<Scene> loadSceneAndCamera(const SceneArgs& a, const std::string& path, const std::string& want, int width,
                                          int height, Camera& camera);
// The same from a file already read (a sequence of frames reads it once).
std::unique_ptr<Scene> loadSceneAndCamera(const SceneArgs& a, const SceneSource& source, const std::string& want, int width,
                                          int height, Camera& camera);

// Core messages name settings by the flags that set them ("--spp must be at
// least 1"; core/util/option_names.h). Call once, first thing in main.
void nameSettingsAsFlags();

// OBSCURA_PLUGIN_PATH, then each --plugin.
void loadPlugins(const std::vector<std::string>& paths);

// "integrator[:key=value,...]" as typed after `option` (-c, --pass): the
// integrator must exist and every assignment must be a valid parameter.
// Throws obscura::Error naming the option and the text.
struct IntegratorSpec {
  std::string integrator;
  std::vector<std::string> assignments;  // key=value, as typed
  std::string canonical;                 // integrator and every parameter's value (":key=value" each)
};
IntegratorSpec parseIntegratorSpec(const std::string& option, const std::string& text);

}  // namespace obscura
