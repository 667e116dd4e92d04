// The environment's tables (docs/math.md §14). The exact irradiance is the
// part with a derivation worth keeping here:
//
// E0(n) = Int L(w) max(0, n.w) dw over the sphere. L is constant over each
// texel, a lat-long rectangle [phi0, phi1] x [theta0, theta1], so over a
// rectangle that lies wholly above n's horizon the integral is L n.M with
// M the rectangle's first moment Int w dw, which has a closed form
// (w = (sin t cos p, cos t, sin t sin p), dw = sin t dt dp):
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
// centre c has n.c >= rho (<= -rho), rho bounding the angle from c to any
// point of the block (sin rho <= rho): rho <= dt/2 + (dp/2) max sin t
// (along the meridian, then along the parallel).
//
// Blocks the horizon crosses are refined down to kLeafRadius (0.025 rad).
// There n.w is nearly linear, and the block's integral is taken as that of
// the positive part of a linear function: with the mean m = n.M / P
// (radiance-weighted, P = Int L dw) and the half-range h of n.w over the
// block's corners, P max(0, m) where the corners agree in sign (exact),
// else P (m + h)^2 / (4h) - the positive part of a value uniform on
// [m - h, m + h]. A horizon along texel edges (an axis-aligned normal on a
// map whose width is a multiple of 4 and height even) is then exact; a
// horizon through texels errs by about pi kLeafRadius^2 / 8 of L in all
// (a relative 8e-5 of E0; measured against brute force well below it:
// tests/test_environment.cpp). 0.025 rad builds a 2048 x 1024 map's table
// in 0.3 s on 2 cores; 0.01 rad took 2.5 s. Texels coarser than kLeafRadius are split into
// s x s equal virtual texels first, so a small map is refined as finely as
// a large one.
//
// The pyramid is stored from level 1 up (level 0, the virtual texels, is
// computed from per-row and per-column tables) - from a coarser base level
// for maps above 2^24 texels, whose base blocks are leaves (a 16384 x 8192
// map: blocks of 4 x 4 texels, 0.0015 rad, 150 MB).
#include "core/scene/environment.h"
#include "core/image/png_check.h"

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
constexpr double kLeafRadius = 2.5e-2;

struct D3 {
  double x = 0, y = 0, z = 0;
};

// body(j) for every row j < H: on TBB's threads for a large map, inline for
// a small one - the constant sky (--sky) builds without waking a worker,
// so a render under it starts TBB exactly as before environments existed.
template <class Body>
void forRows(uint32_t H, size_t texels, const Body& body) {
  if (texels < (size_t(1) << 16)) {
    for (uint32_t j = 0; j < H; ++j) body(j);
  } else {
    tbb::parallel_for(uint32_t(0), H, body);
  }
}

// The solid angle of a texel of row j of a W x H lat-long map.
double rowOmega(uint32_t W, uint32_t H, uint32_t j) {
  return (2.0 * kPiD / W) * (std::cos(kPiD * j / H) - std::cos(kPiD * (j + 1) / H));
}

// Int over a block of max(0, n.w) L dw for a block whose n.w over its
// corners spans [lo, hi], with radiance-weighted first moment dot n.M = nm
// and power P (see the head of the file).
inline double positivePart(double nm, double P, double lo, double hi) {
  if (lo >= 0.0) return nm;
  if (hi <= 0.0 || P <= 0.0) return 0.0;
  const double m = nm / P, h = 0.5 * (hi - lo);
  if (m >= h) return nm;
  if (m <= -h) return 0.0;
  return P * (m + h) * (m + h) / (4.0 * h);
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
  checkPngFitsItsFile(path);
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

// The virtual grid (s x s virtual texels a texel) and its pyramid of block
// sums from `base` up: per node the radiance-weighted first moment (3
// channels x 3 components) and the power Int L dw (3).
struct Environment::Pyramid {
  uint32_t s = 1;           // virtual texels per texel, each way
  uint32_t VW = 0, VH = 0;  // the virtual grid
  // Boundaries of the virtual grid: phi at x = 0..VW, theta at y = 0..VH.
  std::vector<double> phi, sinPhi, cosPhi, theta, sinTheta, cosTheta;
  std::vector<double> A, B;  // per virtual row (the moment's theta factors)
  struct Level {
    uint32_t w = 0, h = 0;
    std::vector<float> node;  // 12 floats a node
    // Per row and per column of this level: the centre's trig, the half
    // extents and the largest sin theta (for rho), and the texel range.
    std::vector<double> cSinT, cCosT, halfT, maxSin, cSinP, cCosP, halfP;
  };
  uint32_t base = 1;
  std::vector<Level> levels;  // levels[l]: l >= base stored; every level has its row/column tables
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
  // Stored four floats a texel: R, G, B and (once the CDFs exist) the
  // texel's density, so a lookup of both touches one cache line.
  texels_.resize(rgb.size() / 3 * 4);
  for (size_t t = 0; t < rgb.size() / 3; ++t)
    for (size_t c = 0; c < 4; ++c) texels_[4 * t + c] = c < 3 ? rgb[3 * t + c] : 0.0f;
  std::vector<float>().swap(rgb);
  view_.texels = texels_.data();
  view_.width = width, view_.height = height;
  view_.constant = true;
  for (size_t i = 4; i < texels_.size() && view_.constant; ++i)
    view_.constant = i % 4 == 3 || texels_[i] == texels_[i % 4];

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
    rowSolidAngle_[j] = float(rowOmega(width, height, j));
  view_.rowSolidAngle = rowSolidAngle_.data();
  rowCos_.resize(size_t(height) + 1);
  for (uint32_t j = 0; j <= height; ++j) rowCos_[j] = float(std::cos(kPiD * j / height));
  view_.rowCos = rowCos_.data();
  if (view_.constant) {
    view_.meanRadiance = Vec3(texels_[0], texels_[1], texels_[2]);
  } else {
    double sum[3] = {0, 0, 0};
    for (uint32_t j = 0; j < height; ++j) {
      const double omega = rowOmega(width, height, j);
      for (uint32_t i = 0; i < width; ++i)
        for (int c = 0; c < 3; ++c) sum[c] += double(texels_[4 * (size_t(j) * width + i) + size_t(c)]) * omega;
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
  forRows(H, size_t(W) * H, [&](uint32_t j) {
    double acc = 0.0;
    float* c = columnCdf_.data() + size_t(j) * (W + 1);
    const float* t = texels_.data() + 4 * size_t(j) * W;
    for (uint32_t i = 0; i < W; ++i) {
      acc += double(luminance(Vec3(t[4 * i], t[4 * i + 1], t[4 * i + 2])));
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
  // The guides (docs/math.md §14.3, "Cost"): an entry per 4 steps of a
  // CDF, so a walk is a step or two and the column guide a quarter of the
  // column CDF's memory (one entry per step measured no faster).
  view_.rowGuideSize = std::max<uint32_t>(1, H / 4);
  view_.columnGuideSize = std::max<uint32_t>(1, W / 4);
  rowGuide_.resize(view_.rowGuideSize);
  EnvironmentView::buildGuide(rowCdf_.data(), H, view_.rowGuideSize, rowGuide_.data());
  columnGuide_.resize(size_t(H) * view_.columnGuideSize);
  forRows(H, size_t(W) * H, [&](uint32_t j) {
    EnvironmentView::buildGuide(columnCdf_.data() + size_t(j) * (W + 1), W, view_.columnGuideSize,
                                columnGuide_.data() + size_t(j) * view_.columnGuideSize);
  });
  view_.rowGuide = rowGuide_.data();
  view_.columnGuide = columnGuide_.data();
  if (view_.samplable)
    forRows(H, size_t(W) * H, [&](uint32_t j) {
      for (uint32_t i = 0; i < W; ++i) texels_[4 * (size_t(j) * W + i) + 3] = view_.texelPdf(i, j);
    });
}

void Environment::buildPyramid() {
  const uint32_t W = view_.width, H = view_.height;
  pyramid_ = std::make_unique<Pyramid>();
  Pyramid& p = *pyramid_;
  // Virtual texels no coarser than kLeafRadius.
  const double coarsest = std::max(2.0 * kPiD / W, kPiD / H);
  p.s = uint32_t(std::max(1.0, std::ceil(coarsest / kLeafRadius)));
  p.VW = W * p.s, p.VH = H * p.s;
  const uint32_t VW = p.VW, VH = p.VH;
  p.phi.resize(VW + 1), p.sinPhi.resize(VW + 1), p.cosPhi.resize(VW + 1);
  for (uint32_t x = 0; x <= VW; ++x) {
    p.phi[x] = 2.0 * kPiD * (double(x) / VW - 0.5);
    p.sinPhi[x] = std::sin(p.phi[x]), p.cosPhi[x] = std::cos(p.phi[x]);
  }
  p.theta.resize(VH + 1), p.sinTheta.resize(VH + 1), p.cosTheta.resize(VH + 1);
  for (uint32_t y = 0; y <= VH; ++y) {
    p.theta[y] = kPiD * y / VH;
    p.sinTheta[y] = std::sin(p.theta[y]), p.cosTheta[y] = std::cos(p.theta[y]);
  }
  p.A.resize(VH), p.B.resize(VH);
  for (uint32_t y = 0; y < VH; ++y) {
    const double dt = p.theta[y + 1] - p.theta[y], st = p.theta[y] + p.theta[y + 1];
    p.A[y] = 0.5 * (dt - std::cos(st) * std::sin(dt));
    p.B[y] = 0.5 * std::sin(st) * std::sin(dt);
  }
  // Levels until one node covers the map, with their row/column tables.
  std::vector<std::pair<uint32_t, uint32_t>> dims{{VW, VH}};
  while (dims.back().first > 1 || dims.back().second > 1)
    dims.push_back({(dims.back().first + 1) / 2, (dims.back().second + 1) / 2});
  p.levels.resize(dims.size());
  for (uint32_t l = 0; l < dims.size(); ++l) {
    Pyramid::Level& L = p.levels[l];
    L.w = dims[l].first, L.h = dims[l].second;
    const uint32_t step = 1u << l;
    for (uint32_t j = 0; j < L.h; ++j) {
      const uint32_t y0 = j * step, y1 = std::min(VH, (j + 1) * step);
      const double tc = 0.5 * (p.theta[y0] + p.theta[y1]);
      L.cSinT.push_back(std::sin(tc)), L.cCosT.push_back(std::cos(tc));
      L.halfT.push_back(0.5 * (p.theta[y1] - p.theta[y0]));
      const bool equator = p.theta[y0] <= 0.5 * kPiD && p.theta[y1] >= 0.5 * kPiD;
      L.maxSin.push_back(equator ? 1.0 : std::max(p.sinTheta[y0], p.sinTheta[y1]));
    }
    for (uint32_t i = 0; i < L.w; ++i) {
      const uint32_t x0 = i * step, x1 = std::min(VW, (i + 1) * step);
      const double pc = 0.5 * (p.phi[x0] + p.phi[x1]);
      L.cSinP.push_back(std::sin(pc)), L.cCosP.push_back(std::cos(pc));
      L.halfP.push_back(0.5 * (p.phi[x1] - p.phi[x0]));
    }
  }
  uint32_t base = 1;
  while (base + 1 < dims.size() && uint64_t(dims[base].first) * dims[base].second > (uint64_t(1) << 22)) ++base;
  p.base = base;
  if (dims.size() <= 1) return;
  // The base level from the texels, then each level from the one below.
  for (uint32_t l = base; l < dims.size(); ++l) {
    Pyramid::Level& L = p.levels[l];
    L.node.assign(size_t(L.w) * L.h * 12, 0.0f);
    tbb::parallel_for(uint32_t(0), L.h, [&](uint32_t j) {
      for (uint32_t i = 0; i < L.w; ++i) {
        double acc[12] = {};
        if (l == base) {
          const uint32_t step = 1u << l;
          for (uint32_t y = j * step; y < std::min(VH, (j + 1) * step); ++y) {
            const double cosDiff = p.cosTheta[y] - p.cosTheta[y + 1];
            for (uint32_t x = i * step; x < std::min(VW, (i + 1) * step); ++x) {
              const double mx = p.A[y] * (p.sinPhi[x + 1] - p.sinPhi[x]), my = p.B[y] * (p.phi[x + 1] - p.phi[x]),
                           mz = p.A[y] * (p.cosPhi[x] - p.cosPhi[x + 1]);
              const double omega = (p.phi[x + 1] - p.phi[x]) * cosDiff;
              const float* t = texels_.data() + 4 * (size_t(y / p.s) * W + x / p.s);
              for (int c = 0; c < 3; ++c) {
                acc[3 * c] += t[c] * mx, acc[3 * c + 1] += t[c] * my, acc[3 * c + 2] += t[c] * mz;
                acc[9 + c] += t[c] * omega;
              }
            }
          }
        } else {
          const Pyramid::Level& C = p.levels[l - 1];
          for (uint32_t y = 2 * j; y < std::min(C.h, 2 * j + 2); ++y)
            for (uint32_t x = 2 * i; x < std::min(C.w, 2 * i + 2); ++x)
              for (int k = 0; k < 12; ++k) acc[k] += C.node[12 * (size_t(y) * C.w + x) + size_t(k)];
        }
        for (int k = 0; k < 12; ++k) L.node[12 * (size_t(j) * L.w + i) + size_t(k)] = float(acc[k]);
      }
    });
  }
}

Vec3 Environment::exactIrradianceOverPi(Vec3 m) const {
  if (view_.constant) return Vec3(texels_[0], texels_[1], texels_[2]);
  const Pyramid& p = *pyramid_;
  const uint32_t W = view_.width, VW = p.VW, VH = p.VH;
  const double len = std::sqrt(double(m.x) * m.x + double(m.y) * m.y + double(m.z) * m.z);
  const D3 n{m.x / len, m.y / len, m.z / len};
  double e[3] = {0, 0, 0};
  // n.w at the virtual grid's boundary point (x, y).
  const auto cornerDot = [&](uint32_t x, uint32_t y) {
    return p.sinTheta[y] * (n.x * p.cosPhi[x] + n.z * p.sinPhi[x]) + n.y * p.cosTheta[y];
  };
  // Depth-first over the blocks the horizon crosses.
  struct Item {
    uint32_t l, i, j;
  };
  Item stack[256];
  int top = 0;
  stack[top++] = {uint32_t(p.levels.size() - 1), 0, 0};
  while (top > 0) {
    const Item it = stack[--top];
    const Pyramid::Level& L = p.levels[it.l];
    const double d = L.cSinT[it.j] * (n.x * L.cCosP[it.i] + n.z * L.cSinP[it.i]) + n.y * L.cCosT[it.j];
    const double rho = L.halfT[it.j] + L.halfP[it.i] * L.maxSin[it.j];
    if (rho < 0.5 * kPiD && d <= -rho) continue;  // wholly below
    // The node's moment and power: stored, or a virtual texel's.
    double mom[9], pow[3];
    if (it.l >= p.base) {
      const float* s = L.node.data() + 12 * (size_t(it.j) * L.w + it.i);
      for (int k = 0; k < 9; ++k) mom[k] = s[k];
      for (int c = 0; c < 3; ++c) pow[c] = s[9 + c];
    } else if (it.l == 0) {
      const uint32_t x = it.i, y = it.j;
      const double mx = p.A[y] * (p.sinPhi[x + 1] - p.sinPhi[x]), my = p.B[y] * (p.phi[x + 1] - p.phi[x]),
                   mz = p.A[y] * (p.cosPhi[x] - p.cosPhi[x + 1]);
      const double omega = (p.phi[x + 1] - p.phi[x]) * (p.cosTheta[y] - p.cosTheta[y + 1]);
      const float* t = texels_.data() + 4 * (size_t(y / p.s) * W + x / p.s);
      for (int c = 0; c < 3; ++c) mom[3 * c] = t[c] * mx, mom[3 * c + 1] = t[c] * my, mom[3 * c + 2] = t[c] * mz,
                                  pow[c] = t[c] * omega;
    } else {
      mom[0] = -1;  // below the stored base (never a leaf): only its children are read
      pow[0] = 0;
    }
    if (rho < 0.5 * kPiD && d >= rho && (it.l >= p.base || it.l == 0)) {  // wholly above
      for (int c = 0; c < 3; ++c) e[c] += n.x * mom[3 * c] + n.y * mom[3 * c + 1] + n.z * mom[3 * c + 2];
      continue;
    }
    const bool leaf = it.l == 0 || (it.l >= p.base && (rho < kLeafRadius || (it.l == p.base && p.base > 1)));
    if (leaf) {
      const uint32_t step = 1u << it.l;
      const uint32_t x0 = it.i * step, x1 = std::min(VW, (it.i + 1) * step);
      const uint32_t y0 = it.j * step, y1 = std::min(VH, (it.j + 1) * step);
      const double c4[4] = {cornerDot(x0, y0), cornerDot(x1, y0), cornerDot(x0, y1), cornerDot(x1, y1)};
      const double lo = std::min({c4[0], c4[1], c4[2], c4[3]}), hi = std::max({c4[0], c4[1], c4[2], c4[3]});
      for (int c = 0; c < 3; ++c)
        e[c] += positivePart(n.x * mom[3 * c] + n.y * mom[3 * c + 1] + n.z * mom[3 * c + 2], pow[c], lo, hi);
      continue;
    }
    const Pyramid::Level& C = p.levels[it.l - 1];
    for (uint32_t y = 2 * it.j; y < std::min(C.h, 2 * it.j + 2); ++y)
      for (uint32_t x = 2 * it.i; x < std::min(C.w, 2 * it.i + 2); ++x) stack[top++] = {it.l - 1, x, y};
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
              const float* t = texels_.data() + 4 * (size_t(j) * W + i);
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
