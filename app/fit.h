// `obscura fit`: the improved-AO paper's method, run on the user's scenes
// (docs/iao_fit.md; docs/math.md §6 "Fitting F0 and F1"). For every covered
// pixel of each scene it renders, in one render with three passes that share
// the camera rays,
//   alpha = ao weighting=uniform        the uniform AO [IAO 4]
//   e0    = gi max-depth=0              F0's data: (1/pi) Int V cos dw [IAO 6]
//   e1    = gi max-depth=1              e1 - e0 = F1's data, the one-bounce
//                                       irradiance over pi [IAO 5]
// under a unit sky with every material white (albedo 1: F1 is defined at
// rho = 1 [IAO 8], the paper's "WE USE ALBEDO=1"). e0 and e1 draw the same
// first-bounce directions (gi's sample dimensions), so e1 - e0 is exactly
// the second segment's light, path by path. The pixels of every scene are
// pooled in one histogram against alpha, F0 and F1 fitted to it by least
// squares (integrators/iao_fit.h), and the coefficients written as JSON
// for `multibounce mapping=fitted fit=FILE`.
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include "app/options.h"

namespace obscura {

struct FitArgs : SceneArgs {
  std::vector<std::string> scenes;  // the CLI defaults it to the bundled scene
  std::string output;               // the coefficients (JSON)
  std::string histogram;            // optional CSV of the bins and the curves
  std::string res = "320x180";
  std::string camera;
  int spp = 256;
  int rays = 4;     // rays (paths) per camera sample of each pass
  int bins = 1000;  // fine: the binning error falls as 1 / bins^2 (integrators/iao_fit.h)
  int threads = 0;
  long long seed = 0;
  bool quiet = false;
};

// Runs the fit; returns the exit code (130 when interrupted through
// `cancel`). Throws obscura::Error naming the option or file on bad input.
int runFit(const FitArgs& args, const std::atomic<bool>* cancel);

}  // namespace obscura
