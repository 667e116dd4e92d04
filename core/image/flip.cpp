// LDR-FLIP and HDR-FLIP from the papers (flip.h names them).
//
// LDR-FLIP compares a test image with a reference as an observer at `ppd`
// pixels per degree sees them when flipping between the two. Per pixel:
//
// Colour pipeline.
//  1. Linear RGB (the sRGB input decoded) -> XYZ (sRGB primaries, D65) ->
//     YCxCz, the linear opponent space: with (x, y, z) = (X/Xn, Y/Yn, Z/Zn)
//     of the white (Xn, Yn, Zn) = XYZ of RGB (1, 1, 1),
//       Y_y = 116 y - 16,  C_x = 500 (x - y),  C_z = 200 (y - z).
//     Linear, so filtering commutes with it.
//  2. Each channel is filtered by its contrast sensitivity function, in the
//     spatial domain a sum of two Gaussians of visual angle r (degrees):
//       S(r) = a1 sqrt(pi/b1) exp(-pi^2 r^2 / b1) + a2 sqrt(pi/b2) exp(-pi^2 r^2 / b2)
//     achromatic (a1, b1, a2, b2) = (1, 0.0047, 0, -), red-green
//     (1, 0.0053, 0, -), blue-yellow (34.1, 0.04, 13.5, 0.025); r = pixel
//     offset / ppd; every kernel spans radius ceil(3 sqrt(0.04 / (2 pi^2)) ppd)
//     (three standard deviations of the widest Gaussian) and is normalised to
//     sum 1, so a constant image is left unchanged. Edges replicate. Each
//     Gaussian is separable: two 1-D passes per term.
//  3. Back to linear RGB, clamped to [0, 1] (the display's gamut), then to
//     CIE L*a*b* (same white) and Hunt-adjusted: a_h = 0.01 L a, b_h = 0.01 L b
//     (chroma looks weaker in the dark).
//  4. HyAB distance: |L_r - L_t| + sqrt((a_r - a_t)^2 + (b_r - b_t)^2), raised to
//     q_c = 0.7, then remapped to [0, 1] with c_max = HyAB(green, blue)^q_c
//     (the largest difference of two colours in the gamut, Hunt-adjusted),
//     p_c = 0.4, p_t = 0.95:
//       dE_c = (p_t / (p_c c_max)) e                                e <  p_c c_max
//            = p_t + (e - p_c c_max) / (c_max - p_c c_max) (1 - p_t)   otherwise
//     (small differences get most of the range).
// Feature pipeline, on the luminance y = Y/Yn = (Y_y + 16) / 116 of the
// unfiltered input, in [0, 1]:
//  5. Edge and point detectors: the first and second x-derivatives of a 2-D
//     Gaussian of standard deviation sigma = 0.5 w ppd pixels, w = 0.082
//     degrees (the peak-to-trough width of the eye's edge detector), radius
//     ceil(3 sigma): K_e(x, y) = -x g, K_p(x, y) = (x^2/sigma^2 - 1) g, with
//     their positive weights scaled to sum 1 and their negative weights to sum
//     -1 (so a unit step answers 1 at the edge); the y detectors are the
//     transposes. Both are a 1-D kernel times the normalised 1-D Gaussian:
//     separable.
//  6. dE_f = ( max(| |e_r| - |e_t| |, | |p_r| - |p_t| |) / sqrt 2 )^q_f, q_f = 0.5,
//     |.| the length of the (x, y) response.
// Combination: dE = dE_c^(1 - dE_f): a feature difference lifts a colour
// difference towards 1. Identical images give dE_c = 0, dE_f = 0 and dE = 0.
//
// HDR-FLIP (HDR paper): an HDR image is judged through the tone mapped
// images a viewer could be shown. For exposures c from `start` (the
// reference's brightest pixel maps to t = 0.85) to `stop` (its median
// luminance maps to 0.85), at least one stop apart and at least two, both
// images are scaled by 2^c, tone mapped per channel by the ACES fit t(x),
// clamped to [0, 1], and compared by LDR-FLIP; a pixel's HDR-FLIP is the
// largest of its LDR-FLIP values. t(x) is Narkowicz's fit
// x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14) of 0.6 x:
//   k0 = 0.6^2 2.51, k1 = 0.6 0.03, k3 = 0.6^2 2.43, k4 = 0.6 0.59, k5 = 0.14.
// The paper then encodes sRGB and LDR-FLIP decodes it: the tone mapped
// values are LDR-FLIP's linear input directly.
#include "core/image/flip.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <obscura/error.h>

namespace obscura {

namespace {

constexpr double kPiD = 3.14159265358979323846;

// sRGB primaries and D65 white (IEC 61966-2-1), linear RGB -> XYZ.
constexpr double kRgbToXyz[3][3] = {{0.4124564, 0.3575761, 0.1804375},
                                    {0.2126729, 0.7151522, 0.0721750},
                                    {0.0193339, 0.1191920, 0.9503041}};

struct ColourSpace {
  double xyzToRgb[3][3];
  double white[3];  // XYZ of RGB (1, 1, 1): the white both spaces are relative to
  ColourSpace() {
    for (int i = 0; i < 3; ++i) white[i] = kRgbToXyz[i][0] + kRgbToXyz[i][1] + kRgbToXyz[i][2];
    // The inverse by cofactors, so RGB -> XYZ -> RGB returns what it was given.
    const auto& m = kRgbToXyz;
    const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                       m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                       m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const int a = (j + 1) % 3, b = (j + 2) % 3, c = (i + 1) % 3, d = (i + 2) % 3;
        xyzToRgb[i][j] = (m[a][c] * m[b][d] - m[a][d] * m[b][c]) / det;
      }
  }
};
const ColourSpace& colourSpace() {
  static const ColourSpace cs;
  return cs;
}

void rgbToXyz(const double rgb[3], double xyz[3]) {
  for (int i = 0; i < 3; ++i) xyz[i] = kRgbToXyz[i][0] * rgb[0] + kRgbToXyz[i][1] * rgb[1] + kRgbToXyz[i][2] * rgb[2];
}

// CIE L*a*b* of linear RGB, Hunt-adjusted (a, b scaled by 0.01 L).
void huntLab(const double rgb[3], double lab[3]) {
  const ColourSpace& cs = colourSpace();
  double xyz[3];
  rgbToXyz(rgb, xyz);
  constexpr double d = 6.0 / 29.0;
  double f[3];
  for (int i = 0; i < 3; ++i) {
    const double t = xyz[i] / cs.white[i];
    f[i] = t > d * d * d ? std::cbrt(t) : t / (3 * d * d) + 4.0 / 29.0;
  }
  lab[0] = 116 * f[1] - 16;
  lab[1] = 0.01 * lab[0] * 500 * (f[0] - f[1]);
  lab[2] = 0.01 * lab[0] * 200 * (f[1] - f[2]);
}

double hyab(const double p[3], const double q[3]) {
  return std::abs(p[0] - q[0]) + std::sqrt((p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]));
}

constexpr double kQc = 0.7, kQf = 0.5, kPc = 0.4, kPt = 0.95;

double cMax() {
  static const double c = [] {
    const double green[3] = {0, 1, 0}, blue[3] = {0, 0, 1};
    double g[3], b[3];
    huntLab(green, g);
    huntLab(blue, b);
    return std::pow(hyab(g, b), kQc);
  }();
  return c;
}

// The colour pipeline's last step (file head, 4) on a HyAB distance.
double remapColour(double distance) {
  const double e = std::pow(distance, kQc), c = cMax(), knee = kPc * c;
  return e < knee ? kPt / knee * e : kPt + (e - knee) / (c - knee) * (1.0 - kPt);
}

// A 1-D kernel of offsets -radius..radius.
struct Kernel {
  int radius = 0;
  std::vector<float> w;
};

// Correlation with a 1-D kernel along x (horizontal) or y, edges replicated.
void filter1d(const std::vector<float>& in, std::vector<float>& out, int width, int height, const Kernel& k,
              bool horizontal) {
  out.resize(in.size());
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y)
      for (int x = 0; x < width; ++x) {
        double s = 0;
        for (int o = -k.radius; o <= k.radius; ++o) {
          const int xx = horizontal ? std::clamp(x + o, 0, width - 1) : x;
          const int yy = horizontal ? y : std::clamp(y + o, 0, height - 1);
          s += double(k.w[size_t(o + k.radius)]) * in[size_t(yy) * size_t(width) + size_t(xx)];
        }
        out[size_t(y) * size_t(width) + size_t(x)] = float(s);
      }
  });
}

// One plane filtered by kx along x, then ky along y.
std::vector<float> separable(const std::vector<float>& in, int width, int height, const Kernel& kx, const Kernel& ky) {
  std::vector<float> tmp, out;
  filter1d(in, tmp, width, height, kx, true);
  filter1d(tmp, out, width, height, ky, false);
  return out;
}

// A contrast sensitivity filter (file head, 2): the sum over its Gaussian
// terms of weight_k * (G_k x G_k), G_k normalised, weight_k the term's share
// of the 2-D kernel's sum.
struct Csf {
  struct Term {
    double weight;
    Kernel g;
  };
  std::vector<Term> terms;
};

Csf csfFilter(double a1, double b1, double a2, double b2, double ppd) {
  const int radius = int(std::ceil(3.0 * std::sqrt(0.04 / (2 * kPiD * kPiD)) * ppd));
  Csf f;
  double total = 0;
  for (const auto& [a, b] : {std::pair{a1, b1}, std::pair{a2, b2}}) {
    if (a == 0) continue;
    Csf::Term t;
    t.g.radius = radius;
    double sum = 0;
    for (int o = -radius; o <= radius; ++o) {
      const double r = o / ppd;
      t.g.w.push_back(float(std::exp(-kPiD * kPiD * r * r / b)));
      sum += t.g.w.back();
    }
    for (float& w : t.g.w) w = float(w / sum);
    // The 2-D term's sum, a sqrt(pi/b) (sum_o g(o))^2, is its weight.
    t.weight = a * std::sqrt(kPiD / b) * sum * sum;
    total += t.weight;
    f.terms.push_back(std::move(t));
  }
  for (Csf::Term& t : f.terms) t.weight /= total;
  return f;
}

std::vector<float> applyCsf(const std::vector<float>& in, int width, int height, const Csf& f) {
  std::vector<float> out(in.size(), 0.0f);
  for (const Csf::Term& t : f.terms) {
    const std::vector<float> part = separable(in, width, height, t.g, t.g);
    for (size_t i = 0; i < out.size(); ++i) out[i] += float(t.weight * part[i]);
  }
  return out;
}

// The feature detectors (file head, 5): the derivative kernel along one axis
// and the normalised Gaussian along the other.
struct FeatureKernels {
  Kernel gauss, edge, point;
};

FeatureKernels featureKernels(double ppd) {
  const double sigma = flipFeatureSigma(ppd);
  const int radius = int(std::ceil(3.0 * sigma));
  FeatureKernels k;
  k.gauss.radius = k.edge.radius = k.point.radius = radius;
  double gs = 0, ePos = 0, eNeg = 0, pPos = 0, pNeg = 0;
  std::vector<double> g, e, p;
  for (int o = -radius; o <= radius; ++o) {
    const double gv = std::exp(-double(o) * o / (2 * sigma * sigma));
    g.push_back(gv), e.push_back(-o * gv), p.push_back((double(o) * o / (sigma * sigma) - 1) * gv);
    gs += gv;
    (e.back() > 0 ? ePos : eNeg) += std::abs(e.back());
    (p.back() > 0 ? pPos : pNeg) += std::abs(p.back());
  }
  // The 2-D kernel's positive weights sum to (sum of the 1-D positive
  // weights) x (sum of g): dividing the 1-D parts by their own sums and g by
  // its sum gives the 2-D normalisation.
  for (size_t i = 0; i < g.size(); ++i) {
    k.gauss.w.push_back(float(g[i] / gs));
    k.edge.w.push_back(float(e[i] / (e[i] > 0 ? ePos : eNeg)));
    k.point.w.push_back(float(p[i] / (p[i] > 0 ? pPos : pNeg)));
  }
  return k;
}

void checkPair(const FlipImage& a, const FlipImage& b, double ppd) {
  if (a.width != b.width || a.height != b.height)
    throw Error("FLIP: image sizes differ: " + std::to_string(b.width) + "x" + std::to_string(b.height) +
                " vs reference " + std::to_string(a.width) + "x" + std::to_string(a.height));
  for (const FlipImage* im : {&a, &b})
    if (im->r.size() != im->pixels() || im->g.size() != im->pixels() || im->b.size() != im->pixels())
      throw Error("FLIP: an image's planes do not match its size");
  if (!(ppd >= 1 && ppd <= 1000)) throw Error("FLIP: pixels per degree must be in [1, 1000], got " + std::to_string(ppd));
}

// One image through the colour pipeline up to the Hunt-adjusted L*a*b*
// (file head, 1-3), and its luminance for the feature pipeline.
struct Prepared {
  std::vector<float> L, a, b, y;
};

Prepared prepare(const FlipImage& im, double ppd) {
  const ColourSpace& cs = colourSpace();
  const size_t n = im.pixels();
  std::vector<float> Yy(n), Cx(n), Cz(n);
  Prepared p;
  p.y.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const double rgb[3] = {std::clamp(double(im.r[i]), 0.0, 1.0), std::clamp(double(im.g[i]), 0.0, 1.0),
                           std::clamp(double(im.b[i]), 0.0, 1.0)};
    double xyz[3];
    rgbToXyz(rgb, xyz);
    const double x = xyz[0] / cs.white[0], y = xyz[1] / cs.white[1], z = xyz[2] / cs.white[2];
    Yy[i] = float(116 * y - 16), Cx[i] = float(500 * (x - y)), Cz[i] = float(200 * (y - z));
    p.y[i] = float(y);
  }
  const std::vector<float> fY = applyCsf(Yy, im.width, im.height, csfFilter(1, 0.0047, 0, 1, ppd));
  const std::vector<float> fX = applyCsf(Cx, im.width, im.height, csfFilter(1, 0.0053, 0, 1, ppd));
  const std::vector<float> fZ = applyCsf(Cz, im.width, im.height, csfFilter(34.1, 0.04, 13.5, 0.025, ppd));
  p.L.resize(n), p.a.resize(n), p.b.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const double y = (fY[i] + 16.0) / 116.0, x = y + fX[i] / 500.0, z = y - fZ[i] / 200.0;
    const double xyz[3] = {x * cs.white[0], y * cs.white[1], z * cs.white[2]};
    double rgb[3];
    for (int c = 0; c < 3; ++c)
      rgb[c] = std::clamp(cs.xyzToRgb[c][0] * xyz[0] + cs.xyzToRgb[c][1] * xyz[1] + cs.xyzToRgb[c][2] * xyz[2], 0.0, 1.0);
    double lab[3];
    huntLab(rgb, lab);
    p.L[i] = float(lab[0]), p.a[i] = float(lab[1]), p.b[i] = float(lab[2]);
  }
  return p;
}

// The ACES fit's coefficients (file head, HDR-FLIP).
constexpr double kK0 = 0.6 * 0.6 * 2.51, kK1 = 0.6 * 0.03, kK3 = 0.6 * 0.6 * 2.43, kK4 = 0.6 * 0.59, kK5 = 0.14;

FlipImage exposed(const FlipImage& im, double exposure) {
  const double s = std::exp2(exposure);
  FlipImage o = im;
  for (std::vector<float>* plane : {&o.r, &o.g, &o.b})
    for (float& v : *plane) v = float(flipAces(s * double(v)));
  return o;
}

}  // namespace

double flipFeatureSigma(double ppd) { return 0.5 * 0.082 * ppd; }

FlipFeatures flipFeatures(const std::vector<float>& luminance, int width, int height, double ppd) {
  const FeatureKernels k = featureKernels(ppd);
  const std::vector<float> ex = separable(luminance, width, height, k.edge, k.gauss);
  const std::vector<float> ey = separable(luminance, width, height, k.gauss, k.edge);
  const std::vector<float> px = separable(luminance, width, height, k.point, k.gauss);
  const std::vector<float> py = separable(luminance, width, height, k.gauss, k.point);
  FlipFeatures f;
  f.edge.resize(luminance.size()), f.point.resize(luminance.size());
  for (size_t i = 0; i < luminance.size(); ++i) {
    f.edge[i] = std::hypot(ex[i], ey[i]);
    f.point[i] = std::hypot(px[i], py[i]);
  }
  return f;
}

double flipColourDifference(const float reference[3], const float test[3]) {
  double r[3], t[3], lr[3], lt[3];
  for (int c = 0; c < 3; ++c) r[c] = std::clamp(double(reference[c]), 0.0, 1.0), t[c] = std::clamp(double(test[c]), 0.0, 1.0);
  huntLab(r, lr);
  huntLab(t, lt);
  return remapColour(hyab(lr, lt));
}

std::vector<float> ldrFlip(const FlipImage& reference, const FlipImage& test, double ppd) {
  checkPair(reference, test, ppd);
  const Prepared r = prepare(reference, ppd), t = prepare(test, ppd);
  const FlipFeatures fr = flipFeatures(r.y, reference.width, reference.height, ppd);
  const FlipFeatures ft = flipFeatures(t.y, reference.width, reference.height, ppd);
  std::vector<float> out(reference.pixels());
  for (size_t i = 0; i < out.size(); ++i) {
    const double pr[3] = {r.L[i], r.a[i], r.b[i]}, pt[3] = {t.L[i], t.a[i], t.b[i]};
    const double colour = remapColour(hyab(pr, pt));
    const double feature = std::pow(
        std::max(std::abs(fr.edge[i] - ft.edge[i]), std::abs(fr.point[i] - ft.point[i])) / std::sqrt(2.0), kQf);
    // 0^0 would be 1: with no colour difference there is nothing to lift.
    out[i] = colour > 0 ? float(std::pow(colour, 1.0 - feature)) : 0.0f;
  }
  return out;
}

double flipAces(double x) {
  x = std::max(x, 0.0);
  if (!std::isfinite(x)) return 1.0;
  const double t = (kK0 * x * x + kK1 * x) / (kK3 * x * x + kK4 * x + kK5);
  return std::clamp(t, 0.0, 1.0);
}

double flipAcesInverse(double t) {
  // (k0 - t k3) x^2 + (k1 - t k4) x - t k5 = 0, the positive root (k0 > t k3
  // for t < 1: the curve's asymptote k0/k3 = 1.033 lies above 1).
  const double a = kK0 - t * kK3, b = kK1 - t * kK4, c = -t * kK5;
  return (-b + std::sqrt(b * b - 4 * a * c)) / (2 * a);
}

FlipExposures flipExposures(const FlipImage& reference, const std::vector<size_t>* pixels) {
  std::vector<double> lum;
  const size_t n = pixels ? pixels->size() : reference.pixels();
  lum.reserve(n);
  for (size_t k = 0; k < n; ++k) {
    const size_t i = pixels ? (*pixels)[k] : k;
    lum.push_back(std::max(0.0, 0.2126 * reference.r[i] + 0.7152 * reference.g[i] + 0.0722 * reference.b[i]));
  }
  FlipExposures e;
  if (lum.empty()) return e;
  std::sort(lum.begin(), lum.end());
  const double maxY = lum.back();
  if (!(maxY > 0) || !std::isfinite(maxY)) return e;
  // The median as the mean of the middle two for an even count.
  double median = lum.size() % 2 ? lum[lum.size() / 2] : 0.5 * (lum[lum.size() / 2 - 1] + lum[lum.size() / 2]);
  if (!(median > 0)) median = *std::upper_bound(lum.begin(), lum.end(), 0.0);
  const double x85 = flipAcesInverse(0.85);
  e.start = std::log2(x85 / maxY);
  e.stop = std::log2(x85 / median);
  e.count = std::max(2, int(std::ceil(e.stop - e.start)));
  return e;
}

std::vector<float> hdrFlip(const FlipImage& reference, const FlipImage& test, const FlipExposures& exposures,
                           double ppd) {
  checkPair(reference, test, ppd);
  if (exposures.count < 1 || exposures.count > 1000)
    throw Error("HDR-FLIP: the number of exposures must be in [1, 1000], got " + std::to_string(exposures.count));
  std::vector<float> out(reference.pixels(), 0.0f);
  const double step = exposures.count > 1 ? (exposures.stop - exposures.start) / (exposures.count - 1) : 0.0;
  for (int k = 0; k < exposures.count; ++k) {
    const double c = exposures.start + k * step;
    const std::vector<float> e = ldrFlip(exposed(reference, c), exposed(test, c), ppd);
    for (size_t i = 0; i < out.size(); ++i) out[i] = std::max(out[i], e[i]);
  }
  return out;
}

}  // namespace obscura
