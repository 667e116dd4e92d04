// `obscura compare`: the speed/accuracy trade of integrator configurations
// against a full-GI reference, on the user's scene (docs/compare.md "Compare").
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include "app/options.h"
#include "core/image/flip.h"

namespace obscura {

struct CompareArgs : SceneArgs {
  std::string scene;
  std::string output;               // DIR
  std::string reference;            // REF.exr, or empty: render (and cache) a gi reference
  int referenceSpp = 1024;
  std::vector<std::string> configs;  // integrator[:key=value,...]
  std::string sppList = "4,16,64";
  int seeds = 1;                    // renders per cell (>= 2: bias^2 and variance)
  std::string targets;              // RMSE targets for the summary; empty: 0.1,0.05,0.02,0.01
  std::string targetsFlip;          // FLIP targets for the summary; empty: none
  double flipPpd = kFlipDefaultPpd;  // FLIP's observer, pixels per degree (docs/compare.md "FLIP")
  std::string res = "320x180";
  std::string camera;
  int threads = 0;
  long long seed = 0;
  std::string sky = "1,1,1";
  EnvironmentArgs env;  // --environment: cells and reference compared by shaded.* (docs/compare.md)
  bool quiet = false;
  std::vector<std::string> plugins;
};

// One parsed CONFIG: the integrator and its parameters as the user typed
// them, and the render settings a config may carry beside them (README
// "Compare"): `target=E` (adaptive sampling to a standard error E of W; the
// cell's spp is then the most a pixel takes), `min-spp=N` (with target) and
// `denoise=on|off`. Those are not integrator parameters: they are taken out
// before the parameters are checked. Throws obscura::Error naming the config
// on a malformed string, an unknown integrator or a bad parameter or setting.
struct CompareConfig {
  std::string text;        // as typed
  std::string integrator;
  std::vector<std::string> assignments;  // key=value, the integrator's parameters only
  // The integrator, every parameter's value and the settings that differ
  // from a plain render (":target=E", ":min-spp=N", ":denoise=on"): the
  // cache key, so a plain config keeps the key it had before these existed.
  std::string canonical;
  double targetError = 0;  // 0: fixed spp
  int minSpp = 0;          // 0: the renderer's default (docs/sampling.md "Adaptive sampling")
  bool denoise = false;
};
CompareConfig parseCompareConfig(const std::string& text);

// Runs the comparison; returns the process exit code (130 when interrupted
// through `cancel`). Throws obscura::Error on bad input.
int runCompare(const CompareArgs& args, const std::atomic<bool>* cancel);

}  // namespace obscura
