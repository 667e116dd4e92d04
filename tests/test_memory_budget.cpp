// Issue #37: memory nobody refused up front. Each hostile input is built
// here and its cost measured by the peak resident set of the CLI.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "tests/gltf_builder.h"
#include "tests/limited_cli.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// The cause of 3.8 GB for 400k leaves under 998 levels: every mesh use
// carried a copy of its ancestor list (4 bytes a level, in the document's
// uses and each pose's). Leaves deep down cost what leaves at the top cost.
TEST(MemoryBudget, DeepLeavesCostNoMoreThanShallowOnes) {
  const std::string dir = tempDir("budget_deep");
  constexpr int kLeaves = 40000, kDepth = 998;
  const auto write = [&](int depth, const std::string& name) {
    GltfBuilder g;
    const int mesh = g.quadMesh(0.01f);
    g.push("cameras", perspective("", 0.8, 0.01));
    std::vector<int> chain;
    for (int i = 0; i < depth; ++i) chain.push_back(g.node(json::object()));
    for (int i = 0; i + 1 < depth; ++i) g.doc["nodes"][size_t(chain[i])]["children"] = {chain[size_t(i) + 1]};
    json leaves = json::array();
    for (int j = 0; j < kLeaves; ++j) leaves.push_back(g.node({{"mesh", mesh}, {"translation", {0.001 * j, 0, 0}}}));
    g.doc["nodes"][size_t(chain.back())]["children"] = leaves;
    g.scene({chain.front(), g.node({{"camera", 0}, {"translation", {0, 0, 3}}})});
    return g.writeGltf(dir, name);
  };
  const LimitedCliResult deep = runCliLimited({"info", write(kDepth, "deep")}, dir + "/deep.txt", 0);
  const LimitedCliResult flat = runCliLimited({"info", write(1, "flat")}, dir + "/flat.txt", 0);
  ASSERT_EQ(deep.exitCode, 0) << deep.stderrText;
  ASSERT_EQ(flat.exitCode, 0) << flat.stderrText;
  // A list per leaf would add kDepth x 4 bytes x 2 copies = 8 KB a leaf
  // (320 MB); a kilobyte a leaf is far above the 997 extra nodes' cost and
  // far below the lists'.
  EXPECT_LT(double(deep.peakRssBytes), double(flat.peakRssBytes) + 1000.0 * kLeaves)
      << "deep " << deep.peakRssBytes << " flat " << flat.peakRssBytes;
}

}  // namespace
}  // namespace obscura::test
