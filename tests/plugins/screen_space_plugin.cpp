// A screen-space integrator built as a plugin, for the loader's tests: the
// seam of core/render/gbuffer.h must work from a separately built library exactly
// as for the built-in `vo` and `ssat` (registration with kind ScreenSpace,
// parameters, estimateTile on the core's tiles).
//
// `covered-neighbours`: W = the fraction of the pixel's neighbours within
// `radius` pixels (a square window, the pixel itself and pixels outside the
// image left out) whose camera sample hit something in this layer. A value
// the test can recompute from the image's coverage channel.
#include <obscura/screen_space.h>
#include <obscura/plugin.h>

namespace {

using namespace obscura;

class CoveredNeighbours final : public ScreenSpaceIntegrator {
 public:
  explicit CoveredNeighbours(int radius) : r_(radius) {}
  void estimateTile(const GBufferLayer& g, const PixelRect& tile, IntegratorContext&,
                    SampleEstimate* out) const override {
    for (int y = tile.y0; y < tile.y1; ++y)
      for (int x = tile.x0; x < tile.x1; ++x) {
        if (!g.covered(g.index(x, y))) continue;
        int covered = 0, total = 0;
        for (int yy = y - r_; yy <= y + r_; ++yy)
          for (int xx = x - r_; xx <= x + r_; ++xx) {
            if (xx < 0 || yy < 0 || xx >= g.width || yy >= g.height || (xx == x && yy == y)) continue;
            ++total;
            covered += g.covered(g.index(xx, yy)) ? 1 : 0;
          }
        const float w = total > 0 ? float(covered) / float(total) : 1.0f;
        out[tile.offset(x, y)].num = Vec3(w, w, w);
      }
  }

 private:
  int r_;
};

IntegratorDescriptor coveredNeighboursDescriptor() {
  IntegratorDescriptor d;
  d.name = "covered-neighbours";
  d.kind = IntegratorKind::ScreenSpace;
  d.doc = "Test plugin (screen-space): the covered fraction of each pixel's neighbours in the G-buffer layer.";
  d.params = {{.name = "radius", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 64,
               .doc = "half-size of the square window of neighbours (pixels)"}};
  d.needs = [](const ParamSet&) { return IntegratorNeeds{}; };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    return std::make_unique<CoveredNeighbours>(p.getInt("radius"));
  };
  return d;
}

}  // namespace

OBSCURA_REGISTER_INTEGRATOR(coveredNeighboursDescriptor)
OBSCURA_PLUGIN_ENTRY("covered-neighbours")
