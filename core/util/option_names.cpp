#include "core/util/option_names.h"

#include <array>

namespace obscura {
namespace {

std::array<std::string, size_t(Setting::Count)> gNames = {
    "spp", "maxMemoryBytes", "subdivision", "backend OpenSubdiv", "displacementMap", "displacementScale",
    "time", "animations", "shutter", "targetError", "minSpp", "timeLimit",
    "backgroundSpp",
};

}  // namespace

const std::string& settingName(Setting s) { return gNames[size_t(s)]; }

void setSettingName(Setting s, std::string name) { gNames[size_t(s)] = std::move(name); }

}  // namespace obscura
