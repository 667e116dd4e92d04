// obscura: the command-line front end (render, merge, integrators, info).
#include <CLI/CLI.hpp>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <sstream>
#include <variant>

#include "core/render/adaptive.h"
#include "core/render/checkpoint.h"
#include <obscura/error.h>
#include "core/render/gbuffer.h"
#include "core/load/gltf_loader.h"
#include "core/image/image_io.h"
#include <obscura/integrator.h>
#include "core/render/plugin_loader.h"
#include <obscura/plugin.h>
#include "core/util/memory_budget.h"
#include "core/util/progress.h"
#include "core/render/pixel_sums.h"
#include "core/render/render.h"
#include "app/options.h"
#include "app/compare.h"
#include "app/fit.h"
#include "app/interrupt.h"
#include "app/merge.h"
#include "app/render_setup.h"
#include "app/sky.h"

using namespace obscura;

namespace {

// Scene-loading options shared by render and compare.
void addEnvironmentOptions(CLI::App* cmd, EnvironmentArgs& a) {
  cmd->add_option("--environment", a.environment,
                  "Light by an equirectangular (lat-long) map, EXR/HDR/any image OpenImageIO reads, mapped as "
                  "Blender's Environment Texture (docs/environment.md); replaces --sky");
  cmd->add_option("--environment-rotation", a.rotation,
                  "Turn the map about the up axis by DEGREES (counter-clockwise seen from above)")
      ->type_name("DEGREES");
  cmd->add_option("--environment-strength", a.strength, "Multiply the map's radiance by S (in [0, 1e30])")
      ->type_name("S");
  cmd->add_option("--environment-irradiance", a.irradiance,
                  "E0(n) of shaded.*: exact (the convolution into a table) or sh9 (nine spherical harmonics)")
      ->check(CLI::IsMember({"exact", "sh9"}));
}

void addSceneOptions(CLI::App* cmd, SceneArgs& a) {
  cmd->add_option("--normal-maps", a.normalMaps,
                  "on: glTF normal maps (normalTexture) bend the shading normal of every pass; off: ignore them");
  cmd->add_option("--subdiv", a.subdiv, "Subdivide OBJ cages: none, catmull-clark or loop (OpenSubdiv, limit normals)");
  cmd->add_option("--subdiv-level", a.subdivLevel, "Uniform subdivision level, 0..10 (each level: 4x the faces)");
  cmd->add_option("--subdiv-backend", a.subdivBackend,
                  "osd: OpenSubdiv refines to triangles at load; embree: Embree's subdivision surfaces (Catmull-Clark), tessellated while the BVH builds");
  cmd->add_option("--subdiv-edge", a.subdivEdge,
                  "Adaptive refinement instead of --subdiv-level: longest refined edge in pixels from the render camera (osd: per mesh, embree: per edge)");
  cmd->add_option("--max-memory", a.maxMemoryGiB,
                  "Memory budget of the process in GiB: a scene, film, texture or image estimated to need more is refused before the work");
  cmd->add_option("--displace", a.displace, "Height map (PNG/EXR/...) displacing a subdivided OBJ cage along its limit normals");
  cmd->add_option("--displace-scale", a.displaceScale, "Displacement: scene units per unit of height");
  cmd->add_option("--displace-midlevel", a.displaceMidlevel, "Displacement: the height that does not move the surface");
  cmd->add_option("--object", a.objects,
                  "Roles of objects by name (glob): GLOB:role=value[,role=value...], roles occluder, camera, matte "
                  "(true/false) and occlusion (all/self/others); repeatable, applied in order after the file's extras");
  // An empty value is refused, not taken as no frame: a farm script whose
  // variable is unset passes `--frame ""`, and out.####.exr would then be
  // written under that very name, every task over the last.
  cmd->add_option("--frame", a.frame,
                  "Apply the glTF animations at this frame (time = FRAME / --fps; fractional allowed; default: the static pose)")
      ->check(CLI::Validator(
          [](std::string& v) { return v.empty() ? std::string("empty frame number (an unset variable?); give a number or leave --frame out") : std::string(); },
          "FRAME"));
  cmd->add_option("--fps", a.fps, "Frames per second of --frame and --frames (> 0)");
  cmd->add_option("--animation", a.animations, "Animations a frame plays: names or indices, comma-separated (default: all)")
      ->delimiter(',');
  cmd->add_option("--shutter", a.shutter,
                  "Motion blur: the shutter OPEN,CLOSE in frames relative to the frame (e.g. -0.25,0.25); needs --frame "
                  "or --frames; ray-traced passes only (default: off)");
}

// One image of a sequence: the frame (empty: none) and its outputs.
struct FrameJob {
  std::string frame;  // as SceneArgs::frame
  std::string output, preview;
};

// The images a render writes: one, or one per frame of --frames, the
// frame number put into the '#' run of -o (and --preview). A single
// --frame given as a whole number fills a '#' run too (what a farm task
// passes); without a frame a '#' is an ordinary character.
std::vector<FrameJob> frameJobs(const RenderArgs& a) {
  if (a.frames.empty()) {
    FrameJob job{a.frame, a.output, a.preview};
    if (a.frame.empty()) return {job};
    const FramePattern po = framePattern("-o", a.output);
    const FramePattern pp = a.preview.empty() ? FramePattern{} : framePattern("--preview", a.preview);
    if (po.any() || pp.any()) {
      const double f = parseFrame(a.frame);
      if (f != std::floor(f))
        throw Error("-o " + a.output + ": a '#' run takes a whole frame number, but --frame is " + a.frame);
      if (po.any()) job.output = frameFileName(a.output, po, (long long)f);
      if (pp.any()) job.preview = frameFileName(a.preview, pp, (long long)f);
    }
    return {job};
  }
  if (!a.frame.empty()) throw Error("--frame: cannot be combined with --frames (one frame, or a range)");
  const std::vector<long long> frames = parseFrameRange(a.frames);
  const FramePattern po = framePattern("-o", a.output);
  if (!po.any())
    throw Error("-o " + a.output + ": --frames needs a '#' run in the output name for the frame number (e.g. out.####.exr)");
  FramePattern pp;
  if (!a.preview.empty()) {
    pp = framePattern("--preview", a.preview);
    if (!pp.any())
      throw Error("--preview " + a.preview + ": --frames needs a '#' run in the preview name too (e.g. out.####.png)");
  }
  std::vector<FrameJob> jobs;
  for (long long f : frames)
    jobs.push_back({std::to_string(f), frameFileName(a.output, po, f), a.preview.empty() ? "" : frameFileName(a.preview, pp, f)});
  return jobs;
}

int runRender(const RenderArgs& args) {
  interrupt::setMessage("obscura: interrupted; " + args.output + " was not written");
  loadPlugins(args.plugins);
  std::vector<PassSetup> setups = passSetups(args);
  RenderSettings s = renderSettings(args);
  if (args.output.empty()) throw Error("-o: an output .exr path is required");
  if (s.environment && !args.quiet) std::fprintf(stderr, "%s", describeEnvironment(*s.environment).c_str());

  std::optional<tbb::global_control> limit;
  if (args.threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(args.threads));

  const bool anyScreenSpace = obscura::anyScreenSpace(setups);
  checkRegionPasses(s, anyScreenSpace);  // before loading the scene
  checkAlbedoPasses(s, setups[0].needs);
  // Every frame's outputs and scene options are checked before the file is read.
  const std::vector<FrameJob> jobs = frameJobs(args);
  const auto inputs = renderInputs(args);  // the same for every frame
  for (const FrameJob& job : jobs) {
    RenderArgs fa = args;
    fa.frame = job.frame, fa.output = job.output, fa.preview = job.preview;
    checkOutputPaths(fa.output, fa.preview, fa.scene, inputs);
    holdFilmMemory(fa, s, screenSpaceBound(setups, s.width, s.height), args.passes.size());
    sceneOptions(fa);
  }
  if (jobs.size() == 1) interrupt::setMessage("obscura: interrupted; " + jobs[0].output + " was not written");
  if (args.checkpointGiven) checkCheckpoint(args, s, anyScreenSpace, jobs[0].output + ".checkpoint");

  std::vector<RenderPass> passes;
  for (const PassSetup& p : setups) passes.push_back({p.integrator.get(), p.needs, p.layer});
  const SceneSource source(args.scene);  // read once; each frame builds its scene from it

  for (size_t j = 0; j < jobs.size(); ++j) {
    RenderArgs a = args;
    a.frame = jobs[j].frame, a.output = jobs[j].output, a.preview = jobs[j].preview;
    const std::string notWritten = "obscura: interrupted; " + a.output + " was not written" +
                                   (jobs.size() > 1 && j + 1 < jobs.size() ? " (nor the later frames)" : "");
    interrupt::setMessage(notWritten);
    if (jobs.size() > 1 && !a.quiet)
      std::fprintf(stderr, "obscura: frame %s (%zu of %zu, %s s) -> %s\n", a.frame.c_str(), j + 1, jobs.size(),
                   formatFloat(parseFrame(a.frame) / a.fps).c_str(), a.output.c_str());
    // --checkpoint (per frame: each output has its own): a damaged file is
    // refused before the scene loads; whether it belongs to this render,
    // once the header's record of it is known.
    RenderSettings fs = s;
    std::optional<Checkpoint> checkpoint;
    if (a.checkpointGiven) {
      checkpoint.emplace(a.output + ".checkpoint", a.checkpoint);
      fs.checkpoint = &*checkpoint;
      checkpoint->read();
    } else if (std::error_code ec; std::filesystem::exists(a.output + ".checkpoint", ec)) {
      std::fprintf(stderr, "obscura: note: %s.checkpoint exists but --checkpoint was not given; rendering from the start\n",
                   a.output.c_str());
    }
    // The film is held against --max-memory while the scene is built and
    // rendered, so the scene's estimate is refused beside it.
    const MemoryHold filmMemory = holdFilmMemory(a, s, screenSpaceBound(setups, s.width, s.height), args.passes.size());
    Camera camera;
    std::unique_ptr<Scene> scene = loadSceneAndCamera(a, source, a.camera, s.width, s.height, camera);

    RenderStats stats;
    const auto header = [&] { return renderHeader(a, setups, camera, fs, stats, *scene); };
    if (checkpoint) {
      checkpoint->setFingerprint(renderFingerprint(a, fs, header()));
      if (checkpoint->loaded() && !a.quiet)
        std::fprintf(stderr, "obscura: resuming from %s (%zu tiles saved)\n", checkpoint->path().c_str(),
                     checkpoint->savedTiles());
    }

    interrupt::startPolling();
    Film film = render(*scene, camera, passes, fs, stats, interrupt::flag());
    if (interrupt::flag()->load()) {
      if (checkpoint)
        std::fprintf(stderr, "%s; %zu of %d tiles saved in %s (run the same command to resume)\n", notWritten.c_str(),
                     checkpoint->savedTiles(), checkpoint->tileCount(), checkpoint->path().c_str());
      else
        std::fprintf(stderr, "%s\n", notWritten.c_str());
      return 130;
    }

    ExrOptions exr = header();
    // A resumed render: how many runs made it (obscura:renderTime sums their
    // render loops; obscura:rays:* count every tile once, as an uninterrupted
    // render does).
    if (checkpoint && checkpoint->runs() > 1) exr.attributes.push_back({"obscura:checkpointRuns", checkpoint->runs()});
    exr.half = a.half;
    exr.compression = exrCompressionFromName(a.compression, "--compression");
    // The pass and its preview land together or not at all.
    OutputSet out;
    out.addExr(a.output, film, exr);
    if (!a.preview.empty()) out.addPreviewPng(a.preview, film);
    out.commit();
    if (checkpoint) checkpoint->remove();  // the image is written: nothing left to resume

    if (!a.quiet) {
      const double total = double(stats.rays.camera + stats.rays.occlusion + stats.rays.closest);
      std::string names;
      for (const PassSetup& p : setups) names += (names.empty() ? "" : " ") + (p.layer.empty() ? "" : p.layer + "=") + p.desc->name;
      const std::string spp = adaptiveSampling(s) ? formatFloat(std::round(stats.meanSpp * 10) / 10) + " spp (mean of " +
                                                        std::to_string(stats.rounds) + " rounds, max " + std::to_string(s.spp) + ")"
                                                  : std::to_string(s.spp) + " spp";
      std::fprintf(stderr, "obscura: %s  %dx%d  %s  %s  %.2f s  %.2f Mrays/s  (BVH %.3f s)\n", a.output.c_str(),
                   s.width, s.height, spp.c_str(), names.c_str(), stats.seconds, total / stats.seconds * 1e-6,
                   scene->buildSeconds());
      if (s.denoise) std::fprintf(stderr, "obscura: denoised in %.3f s (raw pass in noisy.R/G/B)\n", stats.denoiseSeconds);
      if (anyScreenSpace)
        std::fprintf(stderr, "obscura: screen-space split: G-buffer %.3f s, screen-space %.3f s, filter %.3f s\n",
                     stats.gbufferSeconds, stats.screenSpaceSeconds, stats.filterSeconds);
    }
  }
  return 0;
}

int runIntegrators(const std::vector<std::string>& plugins) {
  loadPlugins(plugins);
  for (const auto& d : IntegratorRegistry::instance().all()) {
    std::printf("%s%s\n    %s\n", d.name.c_str(), d.kind == IntegratorKind::ScreenSpace ? " (screen-space)" : "",
                d.doc.c_str());
    for (const auto& p : d.params)
      std::printf("    -p %-10s %-6s %-16s default %-6s %s\n", (p.name + "=").c_str(), p.typeName().c_str(),
                  p.rangeText().c_str(), p.defaultValue.c_str(), p.doc.c_str());
    std::printf("\n");
  }
  return 0;
}

struct InfoArgs : SceneArgs {
  std::string scene;
  EnvironmentArgs env;
  std::string res = "960x540";  // for --subdiv-edge: the image the edges are measured on
  std::string camera;
};

int runInfo(const InfoArgs& a) {
  const std::string& path = a.scene;
  int w = 0, h = 0;
  parseResolution(a.res, w, h);
  Camera camera;
  sceneOptions(a);  // checked before the file is read
  const std::shared_ptr<const Environment> environment = loadEnvironment(a.env, "1,1,1");
  const SceneSource source(path);
  std::unique_ptr<Scene> scene = loadSceneAndCamera(a, source, a.camera, w, h, camera);
  const SceneStats st = scene->stats();
  const Bounds3& b = scene->bounds();
  std::printf("scene      %s\n", path.c_str());
  std::printf("meshes     %zu (%zu baked into world space, %zu instanced)\n", st.meshes, scene->flattenedMeshes,
              scene->instancedMeshes().size());
  std::printf("primitives %zu\n", st.primitives);
  std::printf("triangles  %zu unique, %zu rendered\n", st.uniqueTriangles, st.renderedTriangles);
  if (st.subdivisionFaces > 0) std::printf("subdivision surfaces: %zu cage faces (Embree)\n", st.subdivisionFaces);
  std::printf("instances  %zu\n", st.instances);
  for (const auto& inst : scene->instances())
    std::printf("           %s -> mesh '%s'\n", inst.node.c_str(), scene->instancedMeshes()[size_t(inst.mesh)].name.c_str());
  std::printf("cameras    %zu\n", scene->cameras.size());
  for (size_t i = 0; i < scene->cameras.size(); ++i) {
    const Camera& c = scene->cameras[i];
    const Vec3 p = c.position();
    std::printf("           [%zu] %s  yfov %.4g rad  at (%g, %g, %g)%s\n", i, c.name.c_str(), c.yfov, p.x, p.y, p.z,
                c.animated ? "  (animated)" : "");
  }
  if (const GltfDocument* doc = source.document()) {
    // Every animation of the file, whichever --animation selects; the time
    // range in seconds and in frames at --fps (docs/production.md "Animation and frames").
    const auto& anims = doc->animations();
    std::printf("animations %zu%s\n", anims.size(),
                a.frame.empty() ? "" : ("  (posed at frame " + a.frame + ", " + formatFloat(parseFrame(a.frame) / a.fps) + " s)").c_str());
    for (size_t i = 0; i < anims.size(); ++i) {
      const GltfDocument::AnimationInfo& an = anims[i];
      std::string nodes;
      for (const int n : an.nodes) nodes += (nodes.empty() ? "" : ", ") + doc->nodeLabel(n);
      std::printf("           [%zu] %s  %s - %s s  (frames %s - %s at %s fps)  %zu channel%s  nodes: %s\n", i,
                  an.name.empty() ? ("animations[" + std::to_string(i) + "]").c_str() : an.name.c_str(),
                  formatFloat(an.start).c_str(), formatFloat(an.end).c_str(), formatFloat(an.start * a.fps).c_str(),
                  formatFloat(an.end * a.fps).c_str(), formatFloat(a.fps).c_str(), an.channels, an.channels == 1 ? "" : "s",
                  nodes.empty() ? "none" : nodes.c_str());
    }
  }
  std::printf("objects    %zu\n", scene->objects.size());
  for (const SceneObject& o : scene->objects)
    std::printf("           %s  %s\n", o.name.c_str(), o.roles.isDefault() ? "(default roles)" : o.roles.describe().c_str());
  std::printf("materials  %zu\n", scene->materials.size());
  for (size_t i = 0; i < scene->materials.size(); ++i) {
    const Material& m = scene->materials[i];
    const char* mode = m.alphaMode == AlphaMode::Mask ? "  alphaMode MASK" : m.alphaMode == AlphaMode::Blend ? "  alphaMode BLEND" : "";
    std::printf("           [%zu] %s  baseColorFactor (%g, %g, %g)%s%s", i, m.name.c_str(), m.baseColorFactor.x,
                m.baseColorFactor.y, m.baseColorFactor.z, m.texture >= 0 ? "  x texture" : "", mode);
    if (m.alphaMode != AlphaMode::Opaque) std::printf(" (alpha %g%s)", m.alpha, m.alphaMode == AlphaMode::Mask ? (", cutoff " + formatFloat(m.alphaCutoff)).c_str() : "");
    if (m.normalTexture >= 0) std::printf("  normal map (scale %s)", formatFloat(m.normalScale).c_str());
    std::printf("\n");
  }
  std::printf("textures   %zu\n", scene->textures.size());
  std::printf("cut-outs   %zu primitive%s with alpha (filtered)\n", scene->alphaPrimitives(), scene->alphaPrimitives() == 1 ? "" : "s");
  if (b.empty())
    std::printf("bounds     empty\n");
  else
    std::printf("bounds     (%g, %g, %g) - (%g, %g, %g)\n", b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z);
  std::printf("bvh build  %.3f s\n", scene->buildSeconds());
  std::printf("memory     %.1f MiB in Embree (peak %.1f), %.1f MiB of attributes\n", double(scene->embreeBytes()) / (1 << 20),
              double(scene->embreePeakBytes()) / (1 << 20), double(scene->attributeBytes()) / (1 << 20));
  // What the loader estimated before building (and held to --max-memory),
  // beside the film of a render at --res (docs/cli.md "Memory").
  if (const GltfDocument* doc = source.document()) {
    MemoryEstimate e = estimateSceneMemory(*doc, sceneOptions(a));
    e.add("film at --res", filmBytes(w, h, true));
    std::printf("estimate   %s of %s budget\n", e.describe().c_str(), formatBytes(memoryBudget()).c_str());
  }
  if (environment) std::printf("%s", describeEnvironment(*environment).c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  interrupt::install();  // first: a signal at any point ends with exit code 130 and one line
  nameSettingsAsFlags();
  CLI::App app{"Obscura: film-style ambient passes (AO, obscurance, ambient transfer, GI) as linear EXR."};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("obscura ") + OBSCURA_VERSION);

  RenderArgs r;
  r.scene = OBSCURA_DEFAULT_SCENE;
  CLI::App* render = app.add_subcommand("render", "Render a glTF scene to a multi-channel EXR pass");
  render->option_defaults()->always_capture_default();
  render->add_option("scene", r.scene, "glTF 2.0 scene (.gltf or .glb); default: the bundled scene");
  render->add_option("-o,--output", r.output, "Output EXR path (written atomically)")->required();
  render->add_option("-i,--integrator", r.integrator, "Integrator (see 'obscura integrators')");
  render->add_option("-p,--param", r.params, "Integrator parameter key=value (repeatable)");
  render->add_option("--pass", r.passes,
                     "A pass in its own layer, LAYER=integrator[:key=value,...] (repeatable; replaces -i/-p): the passes "
                     "share camera rays and AOVs, each is written to LAYER.R/G/B and the first also to R,G,B");
  render->add_option("--primary", r.primary, "The --pass layer also written to R,G,B (default: the first)");
  render->add_option("--spp", r.spp, "Camera samples per pixel (with --target-error or --time-limit: the most a pixel takes)");
  render->add_option("--target-error", r.targetError,
                     "Adaptive sampling: a pixel stops once the standard error of its composited pass (absolute; its own "
                     "and pooled over its 3x3 neighbours) is at most E, or at --spp samples (docs/sampling.md \"Adaptive sampling\")")
      ->type_name("E")
      ->default_str("off");
  render->add_flag("--denoise", r.denoise,
                   "Edge-aware denoise of the pass, guided by N, Z, W_error and the objects (docs/sampling.md \"Denoising\"); the raw "
                   "pass is kept as noisy.R/G/B");
  render->add_option("--min-spp", r.minSpp, "Adaptive sampling: the samples every pixel takes before any may stop (but the background, see --background-spp)")
      ->default_str("min(16, --spp)");
  render->add_option("--background-spp", r.backgroundSpp,
                     "Needs --target-error: every pixel first takes this many samples, and one with no surface within "
                     "2 px (none of those 25 pixels' samples hit) stops there; 0: none, every pixel takes --min-spp "
                     "(no survey either when it is not below --min-spp, or for a screen-space primary pass)")
      ->default_str("4");
  render->add_option("--time-limit", r.timeLimit,
                     "Stop sampling at a round boundary: no round starts that is predicted to end past SECONDS of "
                     "render loop (the image then depends on the machine's speed); --min-spp is always completed")
      ->type_name("SECONDS")
      ->default_str("none");
  render->add_option("--res", r.res, "Resolution WIDTHxHEIGHT");
  render->add_option("--camera", r.camera, "Camera name or index in the file, or 'auto' (default: the first camera, else auto)");
  render->add_option("--threads", r.threads, "Worker threads (0 = all cores)");
  render->add_option("--seed", r.seed, "Sampling seed (the image is a pure function of it)");
  render->add_option("--sky", r.sky, "Uniform sky radiance R,G,B (scales the shaded.* AOV)");
  addEnvironmentOptions(render, r.env);
  render->add_option("--preview", r.preview, "Also write an sRGB PNG preview of the pass");
  render->add_option("--filter", r.filter, "Pixel filter: box or gaussian (sigma 0.5 px, radius 1.5 px)");
  render->add_option("--tile", r.tileSize, "Tile size in pixels (does not change the image)");
  render->add_flag("--half", r.half, "Write 16-bit half floats instead of 32-bit floats");
  render->add_option("--compression", r.compression, "EXR compression: none, rle, zips, zip or piz (lossless)")->check(CLI::IsMember({"none", "rle", "zips", "zip", "piz"}, CLI::ignore_case));
  render->add_flag("--no-aovs", r.noAovs, "Write only R,G,B,A (skips albedo, N, Z, shaded)");
  render->add_flag("--no-albedo", r.noAlbedo, "Skip the albedo.* and shaded.* AOVs and, unless the integrator reads albedo, their texture lookups (the other AOVs stay)");
  render->add_flag("-q,--quiet", r.quiet, "No progress bar or summary");
  render->add_option("--plugin", r.plugins, "Load an integrator plugin (shared library); repeatable. Also: OBSCURA_PLUGIN_PATH");
  render->add_option("--cryptomatte", r.cryptomatte, "Cryptomatte ID matte layers: object, material, object,material or none");
  render->add_option("--cryptomatte-ranks", r.cryptomatteRanks, "Cryptomatte: ids (id, coverage pairs) kept per pixel, 1..32");
  render->add_option("--region", r.region,
                     "Render only the pixels [X0,X1) x [Y0,Y1) of the frame, as X0,Y0,X1,Y1: the EXR's data window (its display "
                     "window is the frame); equal to the same pixels of the full render (ray-traced passes only; see 'merge')");
  render->add_option("--frames", r.frames,
                     "Render frames A to B (every STEP-th), A-B[:STEP], each to -o with its '#' run replaced by the "
                     "zero-padded frame number (out.####.exr -> out.0001.exr; --preview likewise); the file is read once");
  render->add_option("--checkpoint", r.checkpoint,
                     "Save finished tiles to OUTPUT.checkpoint at most every SECONDS (0: after every tile) and on Ctrl-C; "
                     "the same command run again resumes from it, bit-identical to an uninterrupted render (ray-traced "
                     "passes only; deleted once the EXR is written)")
      ->type_name("SECONDS")
      ->default_str("off");
  render->add_flag("--robust", r.robust, "Watertight Embree traversal: no ray slips between triangles sharing an edge (slower)");
  addSceneOptions(render, r);

  CompareArgs cmp;
  cmp.scene = OBSCURA_DEFAULT_SCENE;
  CLI::App* compare = app.add_subcommand(
      "compare", "Measure the speed/accuracy trade of integrator configs against a full-GI reference");
  compare->option_defaults()->always_capture_default();
  compare->add_option("scene", cmp.scene, "glTF 2.0 scene; default: the bundled scene");
  compare->add_option("-o,--output", cmp.output, "Output directory (created; results.csv etc.; rerun to resume)")->required();
  compare->add_option("-c,--config", cmp.configs,
                      "integrator[:key=value,...], e.g. ao, obscurance:falloff=sqrt,distance=0.5, transfer:depth=1 "
                      "(repeatable)")->required();
  compare->add_option("--spp", cmp.sppList, "Comma-separated camera samples per pixel for every config");
  auto* refOpt = compare->add_option("--reference", cmp.reference, "Reference pass (EXR of the same view and resolution)");
  compare->add_option("--reference-spp", cmp.referenceSpp, "Without --reference: spp of the cached gi reference")
      ->excludes(refOpt);
  compare->add_option("--seeds", cmp.seeds, "Renders per cell with seeds seed..seed+N-1 (>= 2: bias^2 and variance)");
  compare->add_option("--targets", cmp.targets, "RMSE targets for the summary (default 0.1,0.05,0.02,0.01)");
  compare->add_option("--targets-flip", cmp.targetsFlip, "FLIP targets in (0, 1] for the summary (default none)");
  compare->add_option("--flip-ppd", cmp.flipPpd, "FLIP's observer: pixels per degree (default 67.02: 4K, 0.7 m wide, at 0.7 m)");
  compare->add_option("--res", cmp.res, "Resolution WIDTHxHEIGHT");
  compare->add_option("--camera", cmp.camera, "Camera name or index in the file, or 'auto'");
  compare->add_option("--threads", cmp.threads, "Worker threads (0 = all cores)");
  compare->add_option("--seed", cmp.seed, "First sampling seed");
  compare->add_option("--sky", cmp.sky, "Sky radiance R,G,B (part of the view: the reference cache key)");
  addEnvironmentOptions(compare, cmp.env);
  compare->add_flag("-q,--quiet", cmp.quiet, "No progress (the summary table still goes to stdout)");
  compare->add_flag("--robust", cmp.robust, "Watertight Embree traversal");
  addSceneOptions(compare, cmp);
  compare->add_option("--plugin", cmp.plugins, "Load an integrator plugin; repeatable");

  // obscura fit: the improved-AO fit on the user's scenes (app/fit.h, docs/math.md §6).
  FitArgs fitArgs;
  CLI::App* fit = app.add_subcommand("fit", "Fit the improved-AO mapping's F0 and F1 to renders of scenes (for multibounce mapping=fitted)");
  fit->option_defaults()->always_capture_default();
  fit->add_option("scenes", fitArgs.scenes, "glTF 2.0 scenes whose pixels are pooled; default: the bundled scene");
  fit->add_option("-o,--output", fitArgs.output, "Coefficients file to write (.json, atomically)")->required();
  fit->add_option("--histogram", fitArgs.histogram, "Also write the pooled histogram and the curves as CSV");
  fit->add_option("--bins", fitArgs.bins, "AO bins of the histogram (in [3, 100000])");
  fit->add_option("--res", fitArgs.res, "Resolution WIDTHxHEIGHT of every scene's render");
  fit->add_option("--spp", fitArgs.spp, "Camera samples per pixel");
  fit->add_option("--rays", fitArgs.rays, "Rays (paths) per camera sample of each of the three passes");
  fit->add_option("--camera", fitArgs.camera, "Camera name or index in each file, or 'auto' (default: the first camera, else auto)");
  fit->add_option("--threads", fitArgs.threads, "Worker threads (0 = all cores)");
  fit->add_option("--seed", fitArgs.seed, "Sampling seed");
  fit->add_flag("-q,--quiet", fitArgs.quiet, "No progress (the coefficients still go to stdout)");
  fit->add_flag("--robust", fitArgs.robust, "Watertight Embree traversal");
  addSceneOptions(fit, fitArgs);

  std::string mergeOutput;
  std::vector<std::string> mergeTiles;
  CLI::App* merge = app.add_subcommand("merge", "Assemble region renders (render --region) into the full frame");
  merge->add_option("output", mergeOutput, "The full-frame EXR to write (atomically)")->required();
  merge->add_option("tiles", mergeTiles, "Region EXRs of one render that together cover the frame exactly once")->required();
  double mergeMaxMemoryGiB = double(kDefaultMemoryBudget) / double(uint64_t(1) << 30);
  merge->add_option("--max-memory", mergeMaxMemoryGiB, "Refuse a merge whose frame would need more than this many GiB");
  merge->footer(
      "The result equals a single full render bit for bit: every channel, the data window the frame, the header the "
      "tiles' with obscura:region the frame, obscura:rays:*, renderTime and bvhBuildTime summed over the tiles and "
      "obscura:threads dropped unless all tiles agree, DateTime the merge's. Refused, with one line naming the file and why: tiles whose headers "
      "differ in any other attribute (settings, camera, Cryptomatte manifests), whose display windows or channels differ, "
      "that overlap, or that leave a gap.\n");

  std::vector<std::string> listPlugins;
  CLI::App* integrators = app.add_subcommand("integrators", "List integrators with their parameters");
  integrators->add_option("--plugin", listPlugins, "Load an integrator plugin first; repeatable");
  InfoArgs infoArgs;
  CLI::App* info = app.add_subcommand("info", "Describe a scene: meshes, triangles, instances, cameras, materials, bounds, memory");
  info->add_option("scene", infoArgs.scene, "glTF 2.0 scene or OBJ cage")->required();
  addSceneOptions(info, infoArgs);
  addEnvironmentOptions(info, infoArgs.env);
  info->add_option("--res", infoArgs.res, "WIDTHxHEIGHT the edges of --subdiv-edge are measured on");
  info->add_option("--camera", infoArgs.camera, "Camera --subdiv-edge measures from (name, index or 'auto')");

  // obscura sky: analytic environment maps (app/sky.h, docs/math.md §14.7).
  SkyArgs skyArgs;
  CLI::App* sky = app.add_subcommand("sky", "Write an analytic environment map (equirectangular float RGB EXR)");
  sky->add_option("model", skyArgs.model, "overcast, gradient, texel, half or sunsky")
      ->required()
      ->check(CLI::IsMember(skyModels()));
  sky->add_option("-o,--output", skyArgs.output, "Output EXR path (written atomically)")->required();
  sky->add_option("--res", skyArgs.res, "Resolution WIDTHxHEIGHT (height even but for gradient and texel)")
      ->default_str("512x256; sunsky 2048x1024");
  sky->add_option("-p,--param", skyArgs.params, "Model parameter key=value (repeatable; docs/cli.md \"Analytic environments\")");
  sky->footer(
      "Parameters (defaults): overcast Lz=1 ground=0; gradient a=1 b=0.5 (L = max(0, a + b y)); texel column=W/2 "
      "row=H/4 L=1, or elevation=E azimuth=A; half L=1; sunsky turbidity=3 (2..10) elevation=45 azimuth=0 Lz=1 "
      "sun_diameter=0.53 sun_radiance=1e5*Lz ground=0.1*mean sky. Angles in degrees; azimuth from +X towards +Z.\n");

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "obscura: error: %s (see 'obscura --help')\n", e.what());
    return 2;
  }

  try {
    if (render->parsed()) {
      r.integratorGiven = render->get_option("--integrator")->count() > 0 || render->get_option("--param")->count() > 0;
      r.checkpointGiven = render->get_option("--checkpoint")->count() > 0;
      return runRender(r);
    }
    if (compare->parsed()) return runCompare(cmp, interrupt::flag());
    if (fit->parsed()) {
      if (fitArgs.scenes.empty()) fitArgs.scenes = {OBSCURA_DEFAULT_SCENE};
      return runFit(fitArgs, interrupt::flag());
    }
    if (info->parsed()) return runInfo(infoArgs);
    if (sky->parsed()) return runSky(skyArgs);
    if (merge->parsed()) {
      if (!(mergeMaxMemoryGiB > 0) || !std::isfinite(mergeMaxMemoryGiB) || mergeMaxMemoryGiB > 1e6)
        throw Error("--max-memory: expected a positive number of GiB");
      setMemoryBudget(uint64_t(mergeMaxMemoryGiB * double(uint64_t(1) << 30)));
      mergeRegions(mergeOutput, mergeTiles);
      return 0;
    }
    return runIntegrators(listPlugins);
  } catch (const Error& e) {
    std::fprintf(stderr, "obscura: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "obscura: error: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura: error: %s\n", e.what());
    return 1;
  }
}
