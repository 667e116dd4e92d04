// Per-pixel sums over camera samples and their resolution into the film:
// shared by the ray-traced render loop and the G-buffer layer loop, so a
// pixel means the same whichever produced its samples (core/render/render.h,
// core/render/gbuffer.h).
#pragma once

#include <cmath>
#include <cstdint>

#include "core/render/adaptive.h"
#include "core/image/film.h"
#include <obscura/integrator.h>

namespace obscura {

// Per-pixel sums in double: at high spp a float sum of 2^24 values stops
// growing.
struct Sum3 {
  double x = 0, y = 0, z = 0;
  void add(Vec3 v) { x += double(v.x), y += double(v.y), z += double(v.z); }
};
struct PixelSums {
  Sum3 num, den, albedo, N;
  // Sum of E0(n)/pi over the hits (lit by a non-constant environment), and
  // of the primary pass's SampleEstimate::bent (e0=bent): PixelLighting.
  Sum3 e0, bent;
  double Z;
  uint32_t hits;
  uint32_t object = ~0U;  // the object of the pixel's first hit in sample order (the denoiser's guide)
};

// The sums of a pass that shares its pixel's hits, coverage and AOVs with
// the primary pass of a multi-pass render (core/render/render.h).
struct PassSums {
  Sum3 num, den;
};

// The sums of the pixel's even-indexed samples (sample index 0, 2, 4, ...),
// beside the whole pixel's: the odd half is the difference. The two halves
// are independent estimates of W, which gives the pixel's standard error
// for plain means and ratio estimators alike (docs/math.md §13).
struct HalfSums {
  Sum3 num, den;
  uint32_t hits = 0;
  void add(const SampleEstimate& e) { num.add(e.num), den.add(e.den), hits += 1; }
};

// How the primary pass's shaded.* = albedo x W x lighting is lit
// (include/obscura/integrator.h Shading; docs/math.md §14.6).
struct PixelLighting {
  const EnvironmentView* env = nullptr;
  Shading shading = Shading::Irradiance;
  bool bent = false;     // e0=bent: E0 at the pixel's bent normal
  int plane = -1;        // the film channel of lighting.R (G, B follow), or -1
  // Whether the per-hit sum PixelSums::e0 is needed.
  bool wantsE0() const { return !env->constant && shading == Shading::Irradiance; }
  // The factor of a pixel with hits: the constant sky's L; Lbar; or the
  // mean E0/pi over its hits - at the bent normal with e0=bent, where the
  // pixel has one.
  Vec3 at(const PixelSums& p) const {
    if (env->constant || shading == Shading::MeanRadiance) return env->meanRadiance;
    if (bent) {
      // Normalised in double: a pass's sum may be tiny (vo's moments at
      // R = 1e-30 are ~1e-31, whose float square underflows to 0).
      const double len = std::sqrt(p.bent.x * p.bent.x + p.bent.y * p.bent.y + p.bent.z * p.bent.z);
      if (len > 0.0 && std::isfinite(len))
        return env->irradianceOverPi(Vec3(float(p.bent.x / len), float(p.bent.y / len), float(p.bent.z / len)));
    }
    const double inv = 1.0 / double(p.hits);
    return Vec3(float(p.e0.x * inv), float(p.e0.y * inv), float(p.e0.z * inv));
  }
};

// Sum num / Sum den, one channel; 0/0 is 1 (include/obscura/integrator.h).
inline float resolveRatio(double num, double den) { return den != 0.0 ? float(num / den) : 1.0f; }

// Writes pixel (fx, fy) of `film` from its sums over `spp` camera samples:
// coverage, the pass W (through integrator.resolvePixel) and the AOVs, all
// premultiplied by coverage.
void resolvePixelSums(const PixelSums& p, int spp, const Integrator& integrator, bool wantAlbedo,
                      const PixelLighting& light, Film& film, int fx, int fy);

// Writes the layer planes layer, layer + 1, layer + 2 of pixel (fx, fy) from
// a pass's sums, given the pixel's hits and albedo sum (PixelSums'): W
// premultiplied by coverage, exactly as resolvePixelSums writes R,G,B.
// The standard error of the pixel's W (un-premultiplied, after
// integrator.resolvePixel with the pixel's mean albedo `albedo`) from its
// sums and its even half's (docs/math.md §13): with a and b hits in the even
// and odd halves, se = |W_even - W_odd| sqrt(ab) / (a + b), the largest over
// the channels. 0 for a pixel without hits (the background is exact);
// +inf when one half has no hit (nothing to compare).
float standardError(const Sum3& num, const Sum3& den, uint32_t hits, const HalfSums& even,
                    const Integrator& integrator, Vec3 albedo);

// The error the adaptive schedule decides on (docs/math.md §13): the
// standard error of the composited (premultiplied) pass, what the comp
// shows, from the two halves' composited passes P = (hits / samples) W
// after n samples: se(W) where the pixel is fully covered, and with the
// noise of its coverage where it is not. A half without a hit composites
// to 0, so a sliver of coverage has an estimate too (se(W) has none there).
// kNoSurface for a pixel without a hit (exact background); +inf when n < 2.
float compositedError(const Sum3& num, const Sum3& den, uint32_t hits, const HalfSums& even,
                      const Integrator& integrator, Vec3 albedo, uint32_t n);

// What the W_error plane holds at pixel (fx, fy), once R,G,B,A are
// written: `se` (standardError), or where it is unknown |W|, the largest
// channel of the un-premultiplied pass (the error of a guess of 0).
float writtenError(float se, const Film& film, int fx, int fy);

void resolvePassLayer(const PassSums& q, uint32_t hits, const Sum3& albedo, int spp, const Integrator& integrator,
                      bool wantAlbedo, Film& film, int layer, int fx, int fy);

}  // namespace obscura
