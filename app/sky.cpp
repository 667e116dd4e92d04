// Analytic environments (app/sky.h, docs/math.md §14.7).
#include "app/sky.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>

#include <obscura/environment.h>
#include <obscura/error.h>
#include <obscura/params.h>
#include "app/options.h"
#include "core/image/image_io.h"

namespace obscura {
namespace {

constexpr double kPiD = 3.14159265358979323846;
constexpr double kDeg = kPiD / 180.0;
// A map of at most this many texels (1.6 GB of floats).
constexpr uint64_t kMaxTexels = uint64_t(1) << 27;

[[noreturn]] void fail(const std::string& model, const std::string& key, const std::string& why) {
  throw Error("sky " + model + ": " + key + ": " + why);
}

// Finite, and within [lo, hi] (either may be infinite).
void checkRange(const std::string& model, const std::string& key, double v, double lo, double hi) {
  if (!std::isfinite(v)) fail(model, key, "must be finite, got " + formatFloat(v));
  if (v < lo || v > hi) {
    std::string range = std::isinf(hi) ? ">= " + formatFloat(lo) : "in [" + formatFloat(lo) + ", " + formatFloat(hi) + "]";
    fail(model, key, "must be " + range + ", got " + formatFloat(v));
  }
}

// A radiance: finite as a float and non-negative (what the environment loader accepts).
void checkRadiance(const std::string& model, const std::string& key, double v) {
  checkRange(model, key, v, 0.0, double(std::numeric_limits<float>::max()));
}

void checkSize(const std::string& model, uint32_t w, uint32_t h, bool evenHeight) {
  const std::string res = std::to_string(w) + "x" + std::to_string(h);
  if (w < 1 || h < 1) fail(model, "resolution", "expected at least 1x1, got " + res);
  if (uint64_t(w) * h > kMaxTexels)
    fail(model, "resolution", res + " is more than " + std::to_string(kMaxTexels) + " texels (e.g. 16384x8192)");
  if (evenHeight && h % 2 != 0)
    fail(model, "resolution", "the height must be even (the horizon a texel boundary), got " + res);
}

SkyImage blank(uint32_t w, uint32_t h) {
  SkyImage s;
  s.width = w, s.height = h;
  s.rgb.assign(size_t(w) * h * 3, 0.0f);
  return s;
}

void setTexel(SkyImage& s, uint32_t i, uint32_t j, Vec3 L) {
  float* t = s.rgb.data() + 3 * (size_t(j) * s.width + i);
  t[0] = L.x, t[1] = L.y, t[2] = L.z;
}

Vec3 grey(double v) { return {float(v), float(v), float(v)}; }

// The angle between two unit vectors, accurate for small angles (the sun).
double angleBetween(Vec3 a, Vec3 b) {
  const double ax = a.x, ay = a.y, az = a.z, bx = b.x, by = b.y, bz = b.z;
  const double cx = ay * bz - az * by, cy = az * bx - ax * bz, cz = ax * by - ay * bx;
  return std::atan2(std::sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz);
}

}  // namespace

Vec3 skyTexelDirection(uint32_t width, uint32_t height, uint32_t i, uint32_t j) {
  return latLongToDirection((float(i) + 0.5f) / float(width), (float(j) + 0.5f) / float(height));
}

double skyRowSolidAngle(uint32_t width, uint32_t height, uint32_t j) {
  return 2.0 * kPiD / width * (std::cos(kPiD * j / height) - std::cos(kPiD * (j + 1) / height));
}

Vec3 skyDirection(double elevationDegrees, double azimuthDegrees) {
  const double e = elevationDegrees * kDeg, a = azimuthDegrees * kDeg;
  return {float(std::cos(e) * std::cos(a)), float(std::sin(e)), float(std::cos(e) * std::sin(a))};
}

SkyImage overcastSky(uint32_t width, uint32_t height, const OvercastParams& p) {
  checkSize("overcast", width, height, true);
  checkRadiance("overcast", "Lz", p.Lz);
  checkRadiance("overcast", "ground", p.ground);
  SkyImage s = blank(width, height);
  for (uint32_t j = 0; j < height; ++j)
    for (uint32_t i = 0; i < width; ++i) {
      const double c = skyTexelDirection(width, height, i, j).y;
      setTexel(s, i, j, grey(j < height / 2 ? p.Lz * (1.0 + 2.0 * std::max(c, 0.0)) / 3.0 : p.ground));
    }
  return s;
}

SkyImage gradientSky(uint32_t width, uint32_t height, const GradientParams& p) {
  checkSize("gradient", width, height, false);
  const double big = double(std::numeric_limits<float>::max()) / 2;
  checkRange("gradient", "a", p.a, -big, big);
  checkRange("gradient", "b", p.b, -big, big);
  SkyImage s = blank(width, height);
  for (uint32_t j = 0; j < height; ++j)
    for (uint32_t i = 0; i < width; ++i)
      setTexel(s, i, j, grey(std::max(0.0, p.a + p.b * double(skyTexelDirection(width, height, i, j).y))));
  return s;
}

SkyImage texelSky(uint32_t width, uint32_t height, uint32_t column, uint32_t row, double L) {
  checkSize("texel", width, height, false);
  checkRadiance("texel", "L", L);
  if (column >= width) fail("texel", "column", "must be in [0, " + std::to_string(width) + "), got " + std::to_string(column));
  if (row >= height) fail("texel", "row", "must be in [0, " + std::to_string(height) + "), got " + std::to_string(row));
  SkyImage s = blank(width, height);
  setTexel(s, column, row, grey(L));
  return s;
}

SkyImage texelSkyAt(uint32_t width, uint32_t height, double elevationDegrees, double azimuthDegrees, double L) {
  checkSize("texel", width, height, false);
  checkRange("texel", "elevation", elevationDegrees, -90.0, 90.0);
  checkRange("texel", "azimuth", azimuthDegrees, -360.0, 360.0);
  uint32_t i, j;
  skyTexelOf(width, height, elevationDegrees, azimuthDegrees, i, j);
  return texelSky(width, height, i, j, L);
}

void skyTexelOf(uint32_t width, uint32_t height, double elevationDegrees, double azimuthDegrees, uint32_t& i, uint32_t& j) {
  // As EnvironmentView::texelOf finds it.
  float u, v;
  directionToLatLong(skyDirection(elevationDegrees, azimuthDegrees), u, v);
  i = std::min(width - 1, uint32_t(std::max(0.0f, u * float(width))));
  j = std::min(height - 1, uint32_t(std::max(0.0f, v * float(height))));
}

SkyImage halfSky(uint32_t width, uint32_t height, double L) {
  checkSize("half", width, height, true);
  checkRadiance("half", "L", L);
  SkyImage s = blank(width, height);
  for (uint32_t j = 0; j < height / 2; ++j)
    for (uint32_t i = 0; i < width; ++i) setTexel(s, i, j, grey(L));
  return s;
}

// --- Preetham, Shirley and Smits 1999 ------------------------------------------

double perez(const PerezCoefficients& c, double cosTheta, double gamma) {
  // At the horizon B / cos theta -> -inf (B < 0 for T >= 2): the first
  // factor tends to 1. A floor on cos theta keeps the division finite.
  const double ct = std::max(cosTheta, 1e-6), cg = std::cos(gamma);
  return (1.0 + c.A * std::exp(c.B / ct)) * (1.0 + c.C * std::exp(c.D * gamma) + c.E * cg * cg);
}

void preethamCoefficients(double T, PerezCoefficients& Y, PerezCoefficients& x, PerezCoefficients& y) {
  // [PSS Appendix A.2], the distribution coefficients, linear in T.
  Y = {0.1787 * T - 1.4630, -0.3554 * T + 0.4275, -0.0227 * T + 5.3251, 0.1206 * T - 2.5771, -0.0670 * T + 0.3703};
  x = {-0.0193 * T - 0.2592, -0.0665 * T + 0.0008, -0.0004 * T + 0.2125, -0.0641 * T - 0.8989, -0.0033 * T + 0.0452};
  y = {-0.0167 * T - 0.2608, -0.0950 * T + 0.0092, -0.0079 * T + 0.2102, -0.0441 * T - 1.6537, -0.0109 * T + 0.0529};
}

double preethamZenithLuminance(double T, double thetaS) {
  // [PSS A.2]: Y_z in kcd/m^2, chi = (4/9 - T/120)(pi - 2 theta_s).
  const double chi = (4.0 / 9.0 - T / 120.0) * (kPiD - 2.0 * thetaS);
  return (4.0453 * T - 4.9710) * std::tan(chi) - 0.2155 * T + 2.4192;
}

void preethamZenithChromaticity(double T, double thetaS, double& x, double& y) {
  // [PSS A.2]: x_z = (T^2 T 1) M_x (theta_s^3 theta_s^2 theta_s 1)^T, y_z likewise.
  static constexpr double mx[3][4] = {{0.00166, -0.00375, 0.00209, 0.0},
                                      {-0.02903, 0.06377, -0.03202, 0.00394},
                                      {0.11693, -0.21196, 0.06052, 0.25886}};
  static constexpr double my[3][4] = {{0.00275, -0.00610, 0.00317, 0.0},
                                      {-0.04214, 0.08970, -0.04153, 0.00516},
                                      {0.15346, -0.26756, 0.06670, 0.26688}};
  const double t[3] = {T * T, T, 1.0};
  const double s[4] = {thetaS * thetaS * thetaS, thetaS * thetaS, thetaS, 1.0};
  x = y = 0.0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) x += t[r] * mx[r][c] * s[c], y += t[r] * my[r][c] * s[c];
}

Vec3 xyYToRec709(double x, double y, double Y) {
  if (!(y > 0.0) || !(Y > 0.0)) return {0, 0, 0};
  const double X = x / y * Y, Z = (1.0 - x - y) / y * Y;
  // XYZ -> linear Rec.709 with the D65 white (IEC 61966-2-1).
  const double r = 3.2404542 * X - 1.5371385 * Y - 0.4985314 * Z;
  const double g = -0.9692660 * X + 1.8760108 * Y + 0.0415560 * Z;
  const double b = 0.0556434 * X - 0.2040259 * Y + 1.0572252 * Z;
  return {float(std::max(r, 0.0)), float(std::max(g, 0.0)), float(std::max(b, 0.0))};
}

void sunSkyXyY(const SunSkyParams& p, Vec3 d, double& x, double& y, double& Y) {
  PerezCoefficients cY, cx, cy;
  preethamCoefficients(p.turbidity, cY, cx, cy);
  const double thetaS = (90.0 - p.elevation) * kDeg;
  double xz, yz;
  preethamZenithChromaticity(p.turbidity, thetaS, xz, yz);
  const double gamma = angleBetween(d, skyDirection(p.elevation, p.azimuth));
  const double ct = d.y;
  // [PSS eq. 4]: each quantity is its zenith value times F(theta, gamma) /
  // F(0, theta_s); the zenith luminance is Lz instead of the paper's Y_z.
  Y = p.Lz * perez(cY, ct, gamma) / perez(cY, 1.0, thetaS);
  x = xz * perez(cx, ct, gamma) / perez(cx, 1.0, thetaS);
  y = yz * perez(cy, ct, gamma) / perez(cy, 1.0, thetaS);
}

Vec3 sunSkyRadiance(const SunSkyParams& p, Vec3 d) {
  double x, y, Y;
  sunSkyXyY(p, d, x, y, Y);
  return xyYToRec709(x, y, Y);
}

SkyImage sunSky(uint32_t width, uint32_t height, const SunSkyParams& p, SunSkyInfo* info) {
  const std::string m = "sunsky";
  checkSize(m, width, height, true);
  // [PSS] fit T from 2 to 10; below ~1.65 the luminance factor
  // 1 + A e^(B / cos theta) turns negative towards the zenith.
  checkRange(m, "turbidity", p.turbidity, 2.0, 10.0);
  checkRange(m, "elevation", p.elevation, 0.0, 90.0);
  checkRange(m, "azimuth", p.azimuth, -360.0, 360.0);
  checkRadiance(m, "Lz", p.Lz);
  checkRange(m, "sun_diameter", p.sunDiameter, 0.0, 20.0);
  const double sunL = std::isnan(p.sunRadiance) ? 1e5 * p.Lz : p.sunRadiance;
  checkRadiance(m, "sun_radiance", sunL);
  if (!std::isnan(p.ground)) checkRadiance(m, "ground", p.ground);

  SkyImage s = blank(width, height);
  const uint32_t half = height / 2;
  // The sky above the horizon, and its mean radiance (for the ground).
  double sum[3] = {0, 0, 0}, omega = 0;
  for (uint32_t j = 0; j < half; ++j) {
    const double o = skyRowSolidAngle(width, height, j);
    for (uint32_t i = 0; i < width; ++i) {
      const Vec3 L = sunSkyRadiance(p, skyTexelDirection(width, height, i, j));
      setTexel(s, i, j, L);
      sum[0] += L.x * o, sum[1] += L.y * o, sum[2] += L.z * o, omega += o;
    }
  }
  const Vec3 ground = std::isnan(p.ground) ? Vec3(float(0.1 * sum[0] / omega), float(0.1 * sum[1] / omega),
                                                  float(0.1 * sum[2] / omega))
                                           : grey(p.ground);
  for (uint32_t j = half; j < height; ++j)
    for (uint32_t i = 0; i < width; ++i) setTexel(s, i, j, ground);

  // The sun: each texel above the horizon holds the mean radiance over it,
  // (1 - c) sky + c sun, c the fraction of its solid angle inside the disc,
  // from N x N sub-cells of exact solid angle, in or out by their centre.
  // The disc's power is then right to the sub-cells' discretisation at any
  // resolution, where testing texel centres alone would put 0 or 2x it in a
  // coarse map.
  const Vec3 sun = skyDirection(p.elevation, p.azimuth);
  const double r = 0.5 * p.sunDiameter * kDeg;
  const double thetaS = (90.0 - p.elevation) * kDeg;
  // No point of a texel is farther from its centre than half its height
  // plus half its widest parallel.
  const double margin = kPiD / (2.0 * height) + kPiD / width + 1e-9;
  constexpr int N = 16;
  double sunOmega = 0.0;
  for (uint32_t j = 0; j < half && r > 0.0; ++j) {
    const double t0 = kPiD * j / height, t1 = kPiD * (j + 1) / height;
    if (t1 < thetaS - r || t0 > thetaS + r) continue;  // the angle to the sun is at least |theta - theta_s|
    const double texelOmega = skyRowSolidAngle(width, height, j);
    double subOmega[N];
    for (int b = 0; b < N; ++b)
      subOmega[b] = 2.0 * kPiD / (double(width) * N) *
                    (std::cos(t0 + (t1 - t0) * b / N) - std::cos(t0 + (t1 - t0) * (b + 1) / N));
    for (uint32_t i = 0; i < width; ++i) {
      if (angleBetween(skyTexelDirection(width, height, i, j), sun) > r + margin) continue;
      double in = 0.0;
      for (int b = 0; b < N; ++b)
        for (int a = 0; a < N; ++a) {
          const Vec3 d = latLongToDirection((float(i) + (float(a) + 0.5f) / N) / float(width),
                                            (float(j) + (float(b) + 0.5f) / N) / float(height));
          if (angleBetween(d, sun) <= r) in += subOmega[b];
        }
      if (in <= 0.0) continue;
      sunOmega += in;
      const double c = std::min(1.0, in / texelOmega);
      float* t = s.rgb.data() + 3 * (size_t(j) * width + i);
      for (int k = 0; k < 3; ++k) t[k] = float((1.0 - c) * t[k] + c * sunL);
    }
  }
  if (info) {
    info->sunRadiance = sunL;
    info->ground = ground;
    info->zenithLuminanceKcd = preethamZenithLuminance(p.turbidity, thetaS);
    preethamZenithChromaticity(p.turbidity, thetaS, info->zenithX, info->zenithY);
    info->sunSolidAngle = sunOmega;
  }
  return s;
}

// --- the command ----------------------------------------------------------

namespace {

// "key=value" parameters of one model: each key at most once and one of
// the model's.
class SkyParams {
 public:
  SkyParams(const std::string& model, const std::vector<std::string>& params, const std::vector<std::string>& keys)
      : model_(model) {
    std::string all;
    for (const std::string& k : keys) all += (all.empty() ? "" : ", ") + k;
    for (const std::string& p : params) {
      const size_t eq = p.find('=');
      if (eq == std::string::npos || eq == 0)
        throw Error("sky " + model + ": --param: expected key=value, got '" + p + "'");
      const std::string key = p.substr(0, eq);
      if (std::find(keys.begin(), keys.end(), key) == keys.end())
        throw Error("sky " + model + ": unknown parameter '" + key + "' (" + (all.empty() ? "none" : "one of " + all) + ")");
      if (!values_.emplace(key, p.substr(eq + 1)).second) fail(model, key, "given twice");
    }
  }
  bool has(const std::string& key) const { return values_.count(key) > 0; }
  double number(const std::string& key, double fallback) const {
    const auto it = values_.find(key);
    if (it == values_.end()) return fallback;
    const std::string& text = it->second;
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || *end != '\0' || !std::isfinite(v)) fail(model_, key, "expected a finite number, got '" + text + "'");
    return v;
  }
  uint32_t index(const std::string& key, uint32_t fallback) const {
    const double v = number(key, double(fallback));
    if (v != std::floor(v) || v < 0 || v > 4294967295.0)
      fail(model_, key, "expected a whole number >= 0, got '" + values_.at(key) + "'");
    return uint32_t(v);
  }

 private:
  std::string model_;
  std::map<std::string, std::string> values_;
};

std::string kv(const std::string& k, double v) { return " " + k + "=" + formatFloat(v); }
// The shortest text that reads back as the same float.
std::string formatFloat32(float v) {
  char buf[32];
  for (int prec = 6; prec <= 9; ++prec) {
    std::snprintf(buf, sizeof buf, "%.*g", prec, double(v));
    if (std::strtof(buf, nullptr) == v) break;
  }
  return buf;
}

}  // namespace

const std::vector<std::string>& skyModels() {
  static const std::vector<std::string> models = {"overcast", "gradient", "texel", "half", "sunsky"};
  return models;
}

std::string skyDefaultResolution(const std::string& model) { return model == "sunsky" ? "2048x1024" : "512x256"; }

SkyImage makeSky(const std::string& model, uint32_t width, uint32_t height, const std::vector<std::string>& params,
                 std::string& description) {
  if (model == "overcast") {
    const SkyParams a(model, params, {"Lz", "ground"});
    OvercastParams p;
    p.Lz = a.number("Lz", p.Lz), p.ground = a.number("ground", p.ground);
    description = model + kv("Lz", p.Lz) + kv("ground", p.ground);
    return overcastSky(width, height, p);
  }
  if (model == "gradient") {
    const SkyParams a(model, params, {"a", "b"});
    GradientParams p;
    p.a = a.number("a", p.a), p.b = a.number("b", p.b);
    description = model + kv("a", p.a) + kv("b", p.b);
    return gradientSky(width, height, p);
  }
  if (model == "texel") {
    const SkyParams a(model, params, {"column", "row", "elevation", "azimuth", "L"});
    const double L = a.number("L", 1.0);
    if (a.has("elevation") || a.has("azimuth")) {
      if (a.has("column") || a.has("row"))
        throw Error("sky texel: give column and row, or elevation and azimuth, not both");
      const double e = a.number("elevation", 45.0), az = a.number("azimuth", 0.0);
      SkyImage s = texelSkyAt(width, height, e, az, L);
      uint32_t i, j;
      skyTexelOf(width, height, e, az, i, j);
      description = model + kv("elevation", e) + kv("azimuth", az) + kv("column", i) + kv("row", j) + kv("L", L);
      return s;
    }
    const uint32_t i = a.index("column", width / 2), j = a.index("row", height / 4);
    description = model + kv("column", i) + kv("row", j) + kv("L", L);
    return texelSky(width, height, i, j, L);
  }
  if (model == "half") {
    const SkyParams a(model, params, {"L"});
    const double L = a.number("L", 1.0);
    description = model + kv("L", L);
    return halfSky(width, height, L);
  }
  if (model == "sunsky") {
    const SkyParams a(model, params, {"turbidity", "elevation", "azimuth", "Lz", "sun_diameter", "sun_radiance", "ground"});
    SunSkyParams p;
    p.turbidity = a.number("turbidity", p.turbidity);
    p.elevation = a.number("elevation", p.elevation);
    p.azimuth = a.number("azimuth", p.azimuth);
    p.Lz = a.number("Lz", p.Lz);
    p.sunDiameter = a.number("sun_diameter", p.sunDiameter);
    p.sunRadiance = a.number("sun_radiance", p.sunRadiance);
    p.ground = a.number("ground", p.ground);
    SunSkyInfo info;
    SkyImage s = sunSky(width, height, p, &info);
    description = model + kv("turbidity", p.turbidity) + kv("elevation", p.elevation) + kv("azimuth", p.azimuth) +
                  kv("Lz", p.Lz) + kv("sun_diameter", p.sunDiameter) + kv("sun_radiance", info.sunRadiance) +
                  " ground=" + formatFloat32(info.ground.x) + "," + formatFloat32(info.ground.y) + "," +
                  formatFloat32(info.ground.z) + kv("Yz_kcd", info.zenithLuminanceKcd) + kv("xz", info.zenithX) +
                  kv("yz", info.zenithY) + kv("sun_solid_angle", info.sunSolidAngle);
    return s;
  }
  std::string all;
  for (const std::string& m : skyModels()) all += (all.empty() ? "" : ", ") + m;
  throw Error("sky: unknown model '" + model + "' (one of " + all + ")");
}

int runSky(const SkyArgs& args) {
  if (args.output.empty()) throw Error("-o: an output .exr path is required");
  int w = 0, h = 0;
  parseResolution(args.res.empty() ? skyDefaultResolution(args.model) : args.res, w, h);
  checkWritable(args.output);  // before the work
  std::string description;
  const SkyImage s = makeSky(args.model, uint32_t(w), uint32_t(h), args.params, description);
  writeRgbExr(args.output, int(s.width), int(s.height), s.rgb,
              {{"obscura:version", std::string(OBSCURA_VERSION)},
               {"obscura:sky", description},
               {"obscura:sky:model", args.model},
               {"obscura:upAxis", std::string("+Y")}});
  return 0;
}

}  // namespace obscura
