#include "integrators/ambient_paths.h"

#include <algorithm>
#include <vector>

namespace obscura {
namespace {

// Double-precision RGB for path arithmetic: the per-path sums must round
// exactly like obscurance's double sums (see the header).
struct Rgb {
  double c[3];
};

struct PathState {
  SurfaceHit x;      // current vertex; x.sampleIndex = the path's sample index
  Rgb throughput;    // product of (1 - mu) a along the path (/ q under roulette)
  Rgb sum;           // S = Sum throughput * mu
  Rgb absorbed;      // A = Sum throughput * (1 - mu) * (1 - a)  (tail=closed only)
  uint32_t owner;    // index of the camera hit
  bool self;         // this bounce's direction is below x's geometric plane
  float pdfB;        // this bounce's cosine density at its direction (MIS)
  Rgb light;         // the light sample's contribution if its ray is open (MIS)
  size_t envTexel;   // the texel of this bounce's direction, if it escapes (lit)
};

// Per-thread storage that keeps its memory between batches: the hot loop
// allocates nothing once warm.
struct Scratch {
  std::vector<PathState> paths;
  std::vector<Rgb> num, den;  // per camera hit
  std::vector<Vec3> bent;     // per camera hit: bounce 0's open directions, weighted by mu
  std::vector<Sample2> lightU;                // per path: the light draw's sample (MIS)
  std::vector<EnvironmentView::Draw> draws;  // per path: the light draw's stages (MIS)
};
thread_local Scratch tlsScratch;

inline Rgb splat(double v) { return {{v, v, v}}; }

}  // namespace

void AmbientPaths::estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const {
  // At most kMaxPaths paths in flight: the state and the ray batch stay a few
  // hundred KiB whatever `rays` is (a camera sample's paths are never split).
  const size_t group = std::max<size_t>(1, kMaxPaths / rays);
  for (size_t begin = 0; begin < hits.size(); begin += group) {
    const size_t n = std::min(group, hits.size() - begin);
    estimateGroup(hits.subspan(begin, n), ctx, out + begin);
  }
}

void AmbientPaths::estimateGroup(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const {
  Scratch& s = tlsScratch;
  s.num.assign(hits.size(), splat(0.0));
  s.den.assign(hits.size(), splat(0.0));
  s.bent.assign(hits.size(), Vec3(0, 0, 0));
  s.paths.clear();
  for (size_t i = 0; i < hits.size(); ++i)
    for (uint32_t k = 0; k < rays; ++k) {
      PathState& p = s.paths.emplace_back();
      p.x = lobe.oriented(hits[i]);
      p.x.sampleIndex = hits[i].sampleIndex * rays + k;
      p.throughput = splat(1.0);
      p.sum = splat(0.0);
      p.absorbed = splat(0.0);
      p.owner = uint32_t(i);
    }

  // A finished path adds its estimate to its camera hit, in path order
  // within each bounce (the same order for num and den).
  const auto finish = [&](const PathState& p) {
    Rgb& n = s.num[p.owner];
    Rgb& d = s.den[p.owner];
    for (int c = 0; c < 3; ++c) {
      n.c[c] += p.sum.c[c];
      d.c[c] += closedTail ? p.sum.c[c] + p.absorbed.c[c] : 1.0;
    }
  };

  // The environment: escapes scale by L(w) / Lbar (docs/math.md §14.3).
  const EnvironmentView& env = ctx.environment();
  const bool lit = environment && !env.constant;
  const bool mis = lit && lightSamples && env.samplable;
  double invMean[3] = {1.0, 1.0, 1.0};
  if (lit) {
    const float m[3] = {env.meanRadiance.x, env.meanRadiance.y, env.meanRadiance.z};
    for (int c = 0; c < 3; ++c) invMean[c] = m[c] > 0.0f ? 1.0 / double(m[c]) : 0.0;
  }

  for (uint32_t bounce = 0; !s.paths.empty(); ++bounce) {
    const bool last = bounce >= std::min(depth, kMaxBounces);
    const uint32_t dim = kFirstIntegratorDim + 4 * bounce;
    // The pass's lobe at bounce 0 (p.x is already on its side), the cosine
    // hemisphere after.
    const float sinThetaMax = bounce == 0 ? lobe.sinThetaMax : 1.0f;
    const float tnear = bounce == 0 ? lobe.tnear : 0.0f;
    IntersectBatch& batch = ctx.intersectBatch(s.paths.size());
    for (PathState& p : s.paths) {
      const Sample2 u = Sampler::get2D(p.x.pixelKey, p.x.sampleIndex, dim);
      const Vec3 w = Frame::fromNormal(p.x.ns).toWorld(squareToCosineCone(u.u, u.v, sinThetaMax));
      float tfar = mu.tfar();
      if (estimator == Estimator::Occlusion && !mu.zeroRadius())
        tfar = mu.segment(Sampler::get1D(p.x.pixelKey, p.x.sampleIndex, dim + 1));
      p.self = intoSurface(p.x, w);
      p.pdfB = float(dot(w, p.x.ns)) * kInvPi;
      // A segment shorter than near (tnear > tfar) is inactive: a miss, open.
      if (tfar > 0.0f && !p.self)
        batch.push(spawnOrigin(p.x, w), w, tnear, tfar, p.x);
      else  // blocked by the surface itself, or an empty segment: not traced
        batch.push(spawnOrigin(p.x, w), w, kInfinity, 0.0f, p.x);
    }
    ctx.trace(batch);
    if (mis) {
      // One light direction per path (docs/math.md §14.3): its would-be
      // contribution in p.light, zeroed if its ray is blocked. The cosine
      // batch above is traced already: the batches are separate buffers.
      OcclusionBatch& shadow = ctx.occlusionBatch(s.paths.size());
      // The draws in stages over the batch (EnvironmentView::Draw): their
      // cache misses in the map's tables overlap.
      const size_t n = s.paths.size();
      s.lightU.resize(n);
      s.draws.resize(n);
      for (size_t r = 0; r < n; ++r) {
        const PathState& p = s.paths[r];
        s.lightU[r] = Sampler::get2D(p.x.pixelKey, p.x.sampleIndex, dim + 3);
        env.drawRow(s.lightU[r], s.draws[r]);
      }
      for (size_t r = 0; r < n; ++r) env.drawStart(s.draws[r]);
      for (size_t r = 0; r < n; ++r) env.drawColumn(s.lightU[r], s.draws[r]);
      for (size_t r = 0; r < n; ++r) {
        PathState& p = s.paths[r];
        float pl = 0.0f;
        Vec3 L;
        const Vec3 w = env.drawDirection(s.lightU[r], s.draws[r], pl, L);
        const float cosTheta = dot(w, p.x.ns);
        p.light = splat(0.0);
        if (!(pl > 0.0f) || !(cosTheta > 0.0f) || intoSurface(p.x, w)) {
          shadow.push(spawnOrigin(p.x, w), w, kInfinity, 0.0f, p.x);
          continue;
        }
        const double pb = double(cosTheta) * double(kInvPi), pld = pl;
        const double f = pb / pld * powerHeuristic(pld, pb);
        const double Lc[3] = {double(L.x), double(L.y), double(L.z)};
        for (int c = 0; c < 3; ++c) p.light.c[c] = Lc[c] * invMean[c] * f;
        // [0, R] in vacuum; [0, r], r ~ mu', in the medium: open with probability mu(d).
        const float tfar = mu.segment(Sampler::get1D(p.x.pixelKey, p.x.sampleIndex, dim + 1));
        shadow.push(spawnOrigin(p.x, w), w, 0.0f, tfar, p.x);
      }
      ctx.trace(shadow);
      for (size_t r = 0; r < s.paths.size(); ++r)
        if (shadow.occluded(r)) s.paths[r].light = splat(0.0);
    }

    // The texels of the directions that reach the environment (m > 0
    // below), prefetched all at once: one cache miss each in the map, and
    // in this loop they overlap (docs/math.md §14.3, "Cost").
    if (lit)
      for (size_t r = 0; r < s.paths.size(); ++r) {
        PathState& p = s.paths[r];
        if (p.self || (batch.hit(r) && estimator != Estimator::Distance)) continue;
        p.envTexel = env.texelIndex(batch.dir(r));
        env.prefetch(p.envTexel);
      }

    // Paths that go on are compacted to the front, in order.
    size_t kept = 0;
    for (size_t r = 0; r < s.paths.size(); ++r) {
      PathState& p = s.paths[r];
      const bool self = p.self;
      // mu of this segment: the surface itself (d = 0) gives 0; a miss
      // (escape, beyond R, open segment, inactive ray) gives 1.
      double m = 0.0;
      if (!self && !batch.hit(r)) {
        m = 1.0;
      } else if (!self && estimator == Estimator::Distance) {
        m = mu(double(batch.t(r)));
      }
      if (bounce == 0 && m > 0.0) s.bent[p.owner] += batch.dir(r) * float(m);
      if (!lit) {
        for (int c = 0; c < 3; ++c) p.sum.c[c] += p.throughput.c[c] * m;
      } else {
        // The environment along w, MIS-weighted against the light sample
        // (which already added its own contribution, p.light).
        double wb = 1.0;
        Vec3 L(0, 0, 0);
        if (m > 0.0) {
          float pl = 0.0f;
          L = env.radianceAndPdfAt(p.envTexel, pl);
          if (mis) wb = powerHeuristic(p.pdfB, pl);
        }
        const double Lc[3] = {double(L.x), double(L.y), double(L.z)};
        for (int c = 0; c < 3; ++c) p.sum.c[c] += p.throughput.c[c] * (m * wb * Lc[c] * invMean[c] + p.light.c[c]);
      }
      if (m >= 1.0 || (last && !closedTail)) {
        finish(p);
        continue;
      }
      // The occluder: x itself, or the closest hit (full vertex only if the
      // path goes on).
      Vec3 a = p.x.albedo;
      const bool goOn = !last;
      if (!self) {
        if (goOn)
          ctx.surfaceAt(batch, r, true, p.x.pixelKey, p.x.sampleIndex, p.x);
        a = goOn ? p.x.albedo : ctx.albedoAt(batch, r);
      }
      const double open = 1.0 - m;
      const double ac[3] = {double(a.x), double(a.y), double(a.z)};
      bool alive = false;
      for (int c = 0; c < 3; ++c) {
        if (closedTail) p.absorbed.c[c] += p.throughput.c[c] * (open * (1.0 - ac[c]));
        p.throughput.c[c] *= open * ac[c];
        alive = alive || p.throughput.c[c] > 0.0;
      }
      if (!goOn || !alive) {
        finish(p);
        continue;
      }
      if (roulette && bounce + 1 >= kRouletteStart) {
        const double q =
            std::min(1.0, std::max(p.throughput.c[0], std::max(p.throughput.c[1], p.throughput.c[2])));
        if (double(Sampler::get1D(p.x.pixelKey, p.x.sampleIndex, dim + 2)) >= q) {
          finish(p);
          continue;
        }
        for (double& t : p.throughput.c) t /= q;
      }
      if (kept != r) s.paths[kept] = p;
      ++kept;
    }
    s.paths.resize(kept);
  }

  // Per camera sample: the means over its paths. Without roulette every
  // path's sum is at most 1 - T <= 1, so num <= den up to rounding; the
  // clamp makes W <= 1 exact (and is the one obscurance applies).
  for (size_t i = 0; i < hits.size(); ++i) {
    float n[3], d[3];
    for (int c = 0; c < 3; ++c) {
      d[c] = sampleMean(s.den[i].c[c], rays);
      n[c] = sampleMean(s.num[i].c[c], rays);
      if (!roulette) n[c] = std::min(n[c], d[c]);
    }
    out[i].num = Vec3(n[0], n[1], n[2]);
    out[i].den = Vec3(d[0], d[1], d[2]);
    out[i].bent = s.bent[i];
  }
}

}  // namespace obscura
