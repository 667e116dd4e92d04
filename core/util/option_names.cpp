#include "core/util/option_names.h"

#include <algorithm>
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

std::string nearestNameHint(const std::string& name, const std::vector<std::string>& known) {
  // Edit distance by the two-row dynamic programme (insertions, deletions,
  // substitutions each cost 1).
  const auto distance = [](const std::string& a, const std::string& b) {
    std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
      cur[0] = i;
      for (size_t j = 1; j <= b.size(); ++j)
        cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      std::swap(prev, cur);
    }
    return prev[b.size()];
  };
  std::string best, all;
  size_t bestDistance = std::max<size_t>(2, name.size() / 3) + 1;  // a swap of two letters costs 2
  for (const std::string& k : known) {
    all += (all.empty() ? "" : ", ") + k;
    const size_t d = distance(name, k);
    if (d < bestDistance) bestDistance = d, best = k;
  }
  return (best.empty() ? "" : "; did you mean '" + best + "'?") + " (one of: " + all + ")";
}

}  // namespace obscura
