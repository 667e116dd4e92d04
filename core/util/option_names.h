// The settings core/ names in its error messages and warnings, without
// knowing how a front end spells them. By default a message names the
// setting as the library does (the field of RenderSettings or LoadOptions,
// e.g. "spp must be at least 1"); a front end registers its own spelling once
// at start-up, before any work (the CLI: its flags, "--spp must be at least
// 1"), so users read the name they typed.
#pragma once

#include <string>
#include <vector>

namespace obscura {

enum class Setting {
  Spp,                    // RenderSettings::spp
  MaxMemory,              // LoadOptions::maxMemoryBytes
  Subdivision,            // LoadOptions::subdivision
  SubdivisionBackendOsd,  // LoadOptions::backend set to OpenSubdiv
  Displacement,           // LoadOptions::displacementMap
  DisplacementScale,      // LoadOptions::displacementScale
  Time,                   // LoadOptions::time
  Animations,             // LoadOptions::animations
  Shutter,                // LoadOptions::shutter, RenderSettings::motionBlur
  TargetError,            // RenderSettings::targetError
  MinSpp,                 // RenderSettings::minSpp
  TimeLimit,              // RenderSettings::timeLimit
  BackgroundSpp,          // RenderSettings::backgroundSpp
  Count
};

// How messages name `s`.
const std::string& settingName(Setting s);
// Replaces it (not thread-safe: call before rendering or loading).
void setSettingName(Setting s, std::string name);

// For a name that is not one of `known` (an unknown key in a file, a
// misspelt option): "; did you mean 'K'?" naming the known name nearest to
// it by edit distance (Levenshtein) when it is close - at most a third of
// its length, and at least 2 (two letters swapped) - else nothing; then
// " (one of: a, b, c)".
std::string nearestNameHint(const std::string& name, const std::vector<std::string>& known);

}  // namespace obscura
