// The environment's tables (docs/math.md §14). The exact irradiance is the
// part with a derivation worth keeping here:
//
// E0(n) = Int L(w) max(0, n.w) dw over the sphere. L is constant over each
// texel, a lat-long rectangle [phi0, phi1] x [theta0, theta1], so over a
// texel that lies wholly above n's horizon the integral is L n.M with M the
// texel's first moment Int w dw, which has a closed form (w = (sin t cos p,
// cos t, sin t sin p), dw = sin t dt dp):
//
//   M = ( A (sin p1 - sin p0),  B (p1 - p0),  A (cos p0 - cos p1) ),
//   A = Int sin^2 t dt = (dt - cos(t0 + t1) sin dt) / 2,
//   B = Int cos t sin t dt = sin(t0 + t1) sin dt / 2,     dt = t1 - t0,
//
// (the sum-to-product forms keep their digits for thin rows). A block of
// texels wholly above the horizon contributes the sum of its texels' L M,
// so a pyramid of those sums (each node four children) evaluates E0(n)
// visiting only the blocks the horizon crosses: O(perimeter) nodes per
// normal instead of every texel. A block is wholly above (below) when its
// centre c satisfies n.c >= sin(rho) (<= -sin(rho)), rho bounding the
// angle from c to any point of the block: rho <= dt/2 + (dp/2) max sin t
// (along the meridian, then along the parallel). A texel the horizon
// crosses is split into four until rho < kSplitRadius, where the clamped
// integrand is replaced by max(0, n.M): an error of at most about
// rho Omega / 4 per piece, pi kSplitRadius^2 L in all, a relative 4e-6 of
// E0 for a uniform sky.
//
// Maps above 2^22 texels keep the pyramid from a coarser base level (a
// 16384 x 8192 map: blocks of 8 x 8 texels, 150 MB), and a base block the
// horizon crosses is split with its mean radiance: exact wherever the
// horizon does not cut through detail finer than a block.
#include "core/scene/environment.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "core/image/image_io.h"
#include "core/image/oiio_module.h"
#include "core/util/hash.h"
#include <obscura/error.h>

namespace obscura {
namespace {

constexpr double kPiD = 3.14159265358979323846;
constexpr double kSplitRadius = 2e-3;

struct D3 {
  double x = 0, y = 0, z = 0;
};
inline double dotD(const D3& a, const D3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// A lat-long rectangle, angles in radians (phi from -pi, theta from the up pole).
struct Rect {
  double p0, p1, t0, t1;
};

D3 firstMoment(const Rect& r) {
  const double dt = r.t1 - r.t0, st = r.t0 + r.t1;
  const double A = 0.5 * (dt - std::cos(st) * std::sin(dt));
  const double B = 0.5 * std::sin(st) * std::sin(dt);
  return {A * (std::sin(r.p1) - std::sin(r.p0)), B * (r.p1 - r.p0), A * (std::cos(r.p0) - std::cos(r.p1))};
}

double solidAngle(const Rect& r) { return (r.p1 - r.p0) * (std::cos(r.t0) - std::cos(r.t1)); }

enum class Side { Above, Below, Across };

// Where the rectangle lies against n's horizon (conservative: Across when unsure).
Side sideOf(const D3& n, const Rect& r) {
  const double maxSin = (r.t0 <= 0.5 * kPiD && r.t1 >= 0.5 * kPiD) ? 1.0 : std::max(std::sin(r.t0), std::sin(r.t1));
  const double rho = 0.5 * (r.t1 - r.t0) + 0.5 * (r.p1 - r.p0) * maxSin;
  if (rho >= 0.5 * kPiD) return Side::Across;
  const double tc = 0.5 * (r.t0 + r.t1), pc = 0.5 * (r.p0 + r.p1);
  const D3 c{std::sin(tc) * std::cos(pc), std::cos(tc), std::sin(tc) * std::sin(pc)};
  const double d = dotD(n, c), s = std::sin(rho);
  return d >= s ? Side::Above : (d <= -s ? Side::Below : Side::Across);
}

double rectRadius(const Rect& r) {
  const double maxSin = (r.t0 <= 0.5 * kPiD && r.t1 >= 0.5 * kPiD) ? 1.0 : std::max(std::sin(r.t0), std::sin(r.t1));
  return 0.5 * (r.t1 - r.t0) + 0.5 * (r.p1 - r.p0) * maxSin;
}

// Int over r of max(0, n.w) dw, for a rectangle of constant radiance.
double clampedCosine(const D3& n, const Rect& r, int depth = 0) {
  switch (sideOf(n, r)) {
    case Side::Above:
      return dotD(n, firstMoment(r));
    case Side::Below:
      return 0.0;
    case Side::Across:
      break;
  }
  if (rectRadius(r) < kSplitRadius || depth > 48) return std::max(0.0, dotD(n, firstMoment(r)));
  const double pm = 0.5 * (r.p0 + r.p1), tm = 0.5 * (r.t0 + r.t1);
  return clampedCosine(n, {r.p0, pm, r.t0, tm}, depth + 1) + clampedCosine(n, {pm, r.p1, r.t0, tm}, depth + 1) +
         clampedCosine(n, {r.p0, pm, tm, r.t1}, depth + 1) + clampedCosine(n, {pm, r.p1, tm, r.t1}, depth + 1);
}

// Reads RGB texels (top row first) from an EXR (R, G, B or Y channels) or,
// through OpenImageIO, from any other format.
void readTexels(const std::string& path, uint32_t& width, uint32_t& height, std::vector<float>& rgb) {
  if (isExrFile(path)) {
    const ExrImage img = readExrImage(path);
    const auto find = [&](const char* name) -> int {
      for (size_t c = 0; c < img.names.size(); ++c)
        if (img.names[c] == name) return int(c);
      return -1;
    };
    int ch[3] = {find("R"), find("G"), find("B")};
    if (ch[0] < 0 || ch[1] < 0 || ch[2] < 0) {
      const int y = find("Y");
      if (y < 0) throw Error(path + ": no R, G, B (or Y) channels: not an environment map");
      ch[0] = ch[1] = ch[2] = y;
    }
    width = uint32_t(img.width), height = uint32_t(img.height);
    const size_t n = size_t(width) * height;
    rgb.resize(3 * n);
    for (size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) rgb[3 * i + size_t(c)] = img.planes[size_t(ch[c])][i];
    return;
  }
  int w = 0, h = 0;
  oiioModule(path).readRgb(path, w, h, rgb);
  width = uint32_t(w), height = uint32_t(h);
}

}  // namespace

IrradianceMethod irradianceMethodFromName(const std::string& name, const std::string& what) {
  if (name == "exact") return IrradianceMethod::Exact;
  if (name == "sh9") return IrradianceMethod::Sh9;
  throw Error(what + ": expected exact or sh9, got '" + name + "'");
}

const char* irradianceMethodName(IrradianceMethod m) { return m == IrradianceMethod::Sh9 ? "sh9" : "exact"; }

// The pyramid of block sums from `base` up: per node the first moment
// times radiance (3 channels x 3 components) and the power Int L dw (3).
struct Environment::Pyramid {
  struct Level {
    uint32_t w = 0, h = 0;
    std::vector<float> node;  // 12 floats a node
  };
  uint32_t base = 1;
  std::vector<Level> levels;  // levels[l] for l >= base (lower ones empty)
};

Environment::~Environment() = default;

std::shared_ptr<const Environment> Environment::constant(Vec3 L) {
  std::shared_ptr<Environment> e(new Environment());
  e->build({L.x, L.y, L.z}, 1, 1, "--sky");
  return e;
}

std::shared_ptr<const Environment> Environment::load(const EnvironmentOptions& options) {
  uint32_t w = 0, h = 0;
  std::vector<float> rgb;
  readTexels(options.path, w, h, rgb);
  return fromTexels(std::move(rgb), w, h, options, options.path);
}

std::shared_ptr<const Environment> Environment::fromTexels(std::vector<float> rgb, uint32_t width, uint32_t height,
                                                           const EnvironmentOptions& options,
                                                           const std::string& name) {
  std::shared_ptr<Environment> e(new Environment());
  e->options_ = options;
  e->build(std::move(rgb), width, height, name);
  return e;
}

void Environment::build(std::vector<float> rgb, uint32_t width, uint32_t height, const std::string& name) {
  if (width == 0 || height == 0 || rgb.size() != size_t(width) * height * 3)
    throw Error(name + ": an environment map needs at least one texel");
  static const char* kChannel[3] = {"R", "G", "B"};
  for (size_t i = 0; i < rgb.size(); ++i)
    if (!std::isfinite(rgb[i]) || rgb[i] < 0.0f) {
      const size_t t = i / 3;
      throw Error(name + ": texel (column " + std::to_string(t % width) + ", row " + std::to_string(t / width) +
                  ") channel " + kChannel[i % 3] + " is " + std::to_string(rgb[i]) +
                  ": environment radiance must be finite and >= 0");
    }
  hash_ = Fnv1a64().add(rgb.data(), rgb.size() * sizeof(float)).hex();
  const double strength = options_.strength;
  if (!(strength >= 0.0) || !std::isfinite(strength))
    throw Error("--environment-strength: expected a finite value >= 0, got " + std::to_string(strength));
  if (strength != 1.0)
    for (float& v : rgb) {
      v = float(double(v) * strength);
      if (!std::isfinite(v))
        throw Error(name + ": --environment-strength " + std::to_string(strength) +
                    " makes a texel's radiance overflow a float");
    }
  texels_ = std::move(rgb);
  view_.texels = texels_.data();
  view_.width = width, view_.height = height;
  view_.constant = true;
  for (size_t i = 3; i < texels_.size() && view_.constant; ++i) view_.constant = texels_[i] == texels_[i % 3];

  // The rotation, with multiples of 90 degrees exact.
  double deg = std::fmod(options_.rotationDegrees, 360.0);
  if (deg < 0) deg += 360.0;
  if (deg == 0.0) view_.cosRotation = 1.0f, view_.sinRotation = 0.0f;
  else if (deg == 90.0) view_.cosRotation = 0.0f, view_.sinRotation = 1.0f;
  else if (deg == 180.0) view_.cosRotation = -1.0f, view_.sinRotation = 0.0f;
  else if (deg == 270.0) view_.cosRotation = 0.0f, view_.sinRotation = -1.0f;
  else view_.cosRotation = float(std::cos(deg * kPiD / 180.0)), view_.sinRotation = float(std::sin(deg * kPiD / 180.0));

  // Row solid angles and the mean radiance (1/4pi) Sum L Omega.
  rowSolidAngle_.resize(height);
  for (uint32_t j = 0; j < height; ++j)
    rowSolidAngle_[j] = float(solidAngle({0.0, 2.0 * kPiD / width, kPiD * j / height, kPiD * (j + 1) / height}));
  view_.rowSolidAngle = rowSolidAngle_.data();
  if (view_.constant) {
    view_.meanRadiance = Vec3(texels_[0], texels_[1], texels_[2]);
  } else {
    double sum[3] = {0, 0, 0};
    for (uint32_t j = 0; j < height; ++j) {
      const double omega = solidAngle({0.0, 2.0 * kPiD / width, kPiD * j / height, kPiD * (j + 1) / height});
      for (uint32_t i = 0; i < width; ++i)
        for (int c = 0; c < 3; ++c) sum[c] += double(texels_[3 * (size_t(j) * width + i) + size_t(c)]) * omega;
    }
    view_.meanRadiance = Vec3(float(sum[0] / (4 * kPiD)), float(sum[1] / (4 * kPiD)), float(sum[2] / (4 * kPiD)));
  }
  buildSampling();
  if (!view_.constant) {
    buildPyramid();
    buildIrradiance();
  }
}

void Environment::buildSampling() {
  const uint32_t W = view_.width, H = view_.height;
  rowCdf_.assign(size_t(H) + 1, 0.0f);
  columnCdf_.assign(size_t(H) * (W + 1), 0.0f);
  std::vector<double> rowWeight(H, 0.0);
  tbb::parallel_for(uint32_t(0), H, [&](uint32_t j) {
    double acc = 0.0;
    float* c = columnCdf_.data() + size_t(j) * (W + 1);
    const float* t = texels_.data() + 3 * size_t(j) * W;
    for (uint32_t i = 0; i < W; ++i) {
      acc += double(luminance(Vec3(t[3 * i], t[3 * i + 1], t[3 * i + 2])));
      c[i + 1] = float(acc);
    }
    if (acc > 0.0) {
      for (uint32_t i = 1; i < W; ++i) c[i] = float(double(c[i]) / acc);
      c[W] = 1.0f;
    } else {
      std::fill(c, c + W + 1, 0.0f);
    }
    rowWeight[j] = acc * double(rowSolidAngle_[j]);
  });
  double total = 0.0;
  for (uint32_t j = 0; j < H; ++j) {
    total += rowWeight[j];
    rowCdf_[j + 1] = float(total);
  }
  view_.samplable = total > 0.0;
  if (view_.samplable) {
    for (uint32_t j = 1; j < H; ++j) rowCdf_[j] = float(double(rowCdf_[j]) / total);
    rowCdf_[H] = 1.0f;
  }
  view_.rowCdf = rowCdf_.data();
  view_.columnCdf = columnCdf_.data();
}

void Environment::buildPyramid() {
  const uint32_t W = view_.width, H = view_.height;
  pyramid_ = std::make_unique<Pyramid>();
  Pyramid& p = *pyramid_;
  // Levels until one node covers the map.
  std::vector<std::pair<uint32_t, uint32_t>> dims{{W, H}};
  while (dims.back().first > 1 || dims.back().second > 1)
    dims.push_back({(dims.back().first + 1) / 2, (dims.back().second + 1) / 2});
  p.levels.resize(dims.size());
  uint32_t base = 1;
  while (base + 1 < dims.size() && uint64_t(dims[base].first) * dims[base].second > (uint64_t(1) << 22)) ++base;
  p.base = base;
  if (dims.size() <= 1) return;  // one texel: no blocks
  // The base level from texels, then each level from the one below.
  for (uint32_t l = base; l < dims.size(); ++l) {
    Pyramid::Level& L = p.levels[l];
    L.w = dims[l].first, L.h = dims[l].second;
    L.node.assign(size_t(L.w) * L.h * 12, 0.0f);
    tbb::parallel_for(uint32_t(0), L.h, [&](uint32_t j) {
      for (uint32_t i = 0; i < L.w; ++i) {
        double s[12] = {};
        if (l == base) {
          const uint32_t step = 1u << l;
          for (uint32_t y = j * step; y < std::min(H, (j + 1) * step); ++y)
            for (uint32_t x = i * step; x < std::min(W, (i + 1) * step); ++x) {
              const Rect r{2 * kPiD * (double(x) / W - 0.5), 2 * kPiD * (double(x + 1) / W - 0.5), kPiD * y / H,
                           kPiD * (y + 1) / H};
              const D3 m = firstMoment(r);
              const double omega = double(rowSolidAngle_[y]);
              const float* t = texels_.data() + 3 * (size_t(y) * W + x);
              for (int c = 0; c < 3; ++c) {
                s[3 * c] += t[c] * m.x, s[3 * c + 1] += t[c] * m.y, s[3 * c + 2] += t[c] * m.z;
                s[9 + c] += t[c] * omega;
              }
            }
        } else {
          const Pyramid::Level& C = p.levels[l - 1];
          for (uint32_t y = 2 * j; y < std::min(C.h, 2 * j + 2); ++y)
            for (uint32_t x = 2 * i; x < std::min(C.w, 2 * i + 2); ++x)
              for (int k = 0; k < 12; ++k) s[k] += C.node[12 * (size_t(y) * C.w + x) + size_t(k)];
        }
        for (int k = 0; k < 12; ++k) L.node[12 * (size_t(j) * L.w + i) + size_t(k)] = float(s[k]);
      }
    });
  }
}

Vec3 Environment::exactIrradianceOverPi(Vec3 m) const {
  const uint32_t W = view_.width, H = view_.height;
  if (view_.constant) return Vec3(texels_[0], texels_[1], texels_[2]);
  const double len = std::sqrt(double(m.x) * m.x + double(m.y) * m.y + double(m.z) * m.z);
  const D3 n{m.x / len, m.y / len, m.z / len};
  double e[3] = {0, 0, 0};
  const auto texelRect = [&](uint32_t x0, uint32_t x1, uint32_t y0, uint32_t y1) {
    return Rect{2 * kPiD * (double(x0) / W - 0.5), 2 * kPiD * (double(x1) / W - 0.5), kPiD * y0 / H, kPiD * y1 / H};
  };
  const auto texel = [&](uint32_t x, uint32_t y) {
    const double k = clampedCosine(n, texelRect(x, x + 1, y, y + 1));
    const float* t = texels_.data() + 3 * (size_t(y) * W + x);
    for (int c = 0; c < 3; ++c) e[c] += t[c] * k;
  };
  const Pyramid& p = *pyramid_;
  if (p.levels.size() <= 1) {
    texel(0, 0);
  } else {
    // Depth-first over the blocks the horizon crosses.
    struct Item {
      uint32_t l, i, j;
    };
    std::vector<Item> stack{{uint32_t(p.levels.size() - 1), 0, 0}};
    while (!stack.empty()) {
      const Item it = stack.back();
      stack.pop_back();
      const uint32_t step = 1u << it.l;
      const Rect r = texelRect(it.i * step, std::min(W, (it.i + 1) * step), it.j * step, std::min(H, (it.j + 1) * step));
      const Side side = sideOf(n, r);
      if (side == Side::Below) continue;
      const Pyramid::Level& L = p.levels[it.l];
      const float* s = L.node.data() + 12 * (size_t(it.j) * L.w + it.i);
      if (side == Side::Above) {
        for (int c = 0; c < 3; ++c) e[c] += n.x * s[3 * c] + n.y * s[3 * c + 1] + n.z * s[3 * c + 2];
        continue;
      }
      if (it.l == p.base && p.base > 1) {  // a base block: its mean radiance
        const double k = clampedCosine(n, r) / solidAngle(r);
        for (int c = 0; c < 3; ++c) e[c] += s[9 + c] * k;
        continue;
      }
      for (uint32_t y = 2 * it.j; y < 2 * it.j + 2; ++y)
        for (uint32_t x = 2 * it.i; x < 2 * it.i + 2; ++x) {
          if (it.l == 1) {
            if (x < W && y < H) texel(x, y);
          } else if (x < p.levels[it.l - 1].w && y < p.levels[it.l - 1].h) {
            stack.push_back({it.l - 1, x, y});
          }
        }
    }
  }
  return Vec3(float(e[0] / kPiD), float(e[1] / kPiD), float(e[2] / kPiD));
}

Vec3 Environment::sh9IrradianceOverPi(Vec3 m) const { return view_.evalSh9(normalize(m)); }

void Environment::buildIrradiance() {
  const uint32_t W = view_.width, H = view_.height;
  // SH9 coefficients: Sum over texels of L Y_k Omega, each texel by the
  // midpoint rule on s x s pieces (s >= 1, at least 32 rows in all).
  const uint32_t s = std::max<uint32_t>(1, (32 + H - 1) / H);
  using Coeffs = std::array<double, 27>;
  const Coeffs sh = tbb::parallel_reduce(
      tbb::blocked_range<uint32_t>(0, H), Coeffs{},
      [&](const tbb::blocked_range<uint32_t>& rows, Coeffs acc) {
        for (uint32_t j = rows.begin(); j != rows.end(); ++j)
          for (uint32_t b = 0; b < s; ++b) {
            const double t0 = kPiD * (j + double(b) / s) / H, t1 = kPiD * (j + double(b + 1) / s) / H;
            const double omega = (2 * kPiD / (double(W) * s)) * (std::cos(t0) - std::cos(t1));
            for (uint32_t i = 0; i < W; ++i) {
              const float* t = texels_.data() + 3 * (size_t(j) * W + i);
              for (uint32_t a = 0; a < s; ++a) {
                const float u = float((i + (a + 0.5) / s) / W), v = float(0.5 * (t0 + t1) / kPiD);
                float basis[9];
                EnvironmentView::sh9Basis(latLongToDirection(u, v), basis);
                for (int k = 0; k < 9; ++k)
                  for (int c = 0; c < 3; ++c) acc[size_t(3 * k + c)] += double(t[c]) * basis[k] * omega;
              }
            }
          }
        return acc;
      },
      [](Coeffs a, const Coeffs& b) {
        for (size_t k = 0; k < a.size(); ++k) a[k] += b[k];
        return a;
      });
  for (size_t k = 0; k < 27; ++k) view_.sh[k] = float(sh[k]);

  // The exact table, one node per task.
  const uint32_t TW = kIrradianceWidth, TH = kIrradianceHeight;
  irradiance_.assign(size_t(TW) * TH * 3, 0.0f);
  tbb::parallel_for(uint32_t(0), TW * TH, [&](uint32_t k) {
    const uint32_t i = k % TW, j = k / TW;
    const Vec3 e = exactIrradianceOverPi(latLongToDirection(float(i) / TW, float(j) / (TH - 1)));
    float* o = irradiance_.data() + 3 * size_t(k);
    o[0] = e.x, o[1] = e.y, o[2] = e.z;
  });
  view_.irradiance = irradiance_.data();
  view_.irradianceWidth = TW, view_.irradianceHeight = TH;

  // The SH error over the nodes, weighted by the solid angle each stands for.
  double sumW = 0, sumE = 0, sumSq = 0, maxAbs = 0;
  for (uint32_t j = 0; j < TH; ++j) {
    const double t = kPiD * j / (TH - 1);
    const double w = j == 0 || j == TH - 1 ? 1 - std::cos(0.5 * kPiD / (TH - 1)) : std::sin(t) * (kPiD / (TH - 1));
    for (uint32_t i = 0; i < TW; ++i) {
      const float* o = irradiance_.data() + 3 * (size_t(j) * TW + i);
      const double exact = luminance(Vec3(o[0], o[1], o[2]));
      const double approx = luminance(view_.evalSh9(latLongToDirection(float(i) / TW, float(j) / (TH - 1))));
      sumW += w, sumE += w * exact, sumSq += w * (approx - exact) * (approx - exact);
      maxAbs = std::max(maxAbs, std::fabs(approx - exact));
    }
  }
  const double mean = sumE / sumW;
  if (mean > 0) shError_ = {maxAbs / mean, std::sqrt(sumSq / sumW) / mean};
  view_.sh9 = options_.irradiance == IrradianceMethod::Sh9;
}

}  // namespace obscura
