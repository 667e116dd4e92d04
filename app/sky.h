// Analytic environments (docs/math.md §14.7): equirectangular RGB maps made
// from closed-form skies, to test the environment lighting against closed
// forms and to demonstrate it without downloading a map. `obscura sky`
// writes them as float32 RGB EXRs (docs/cli.md
// "Analytic environments").
//
// Every model is a pure function of its parameters and the resolution. The
// maps are in the lat-long layout of include/obscura/environment.h: width W,
// height H, RGB interleaved, top row first; texel (i, j) covers u in
// [i, i + 1) / W and v in [j, j + 1) / H and holds the radiance in the
// direction latLongToDirection(u, v) of its centre (glTF frame, +Y up),
// except where a model says otherwise (the sun disc of sunsky: its
// texels hold the mean over the texel).
//
// Directions are given as elevation (degrees above the horizon) and
// azimuth (degrees from +X towards +Z, i.e. turning right as seen from
// above, like a compass bearing): azimuth a is the map's column
// u = 1/2 + a/360 (mod 1), so +X (0) is the middle column and +Z (90) three
// quarters across. With --environment-rotation phi a feature at azimuth a
// lights the scene from azimuth a - phi.
//
// Parameters are checked (finite, in range) and a bad one is an
// obscura::Error naming the model and the parameter.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <obscura/math.h>

namespace obscura {

struct SkyImage {
  uint32_t width = 0, height = 0;
  std::vector<float> rgb;  // width x height texels, RGB interleaved, top row first
};

// The unit direction of the centre of texel (i, j) (latLongToDirection).
Vec3 skyTexelDirection(uint32_t width, uint32_t height, uint32_t i, uint32_t j);
// The exact solid angle of a texel of row j: (2 pi / W)(cos theta_j -
// cos theta_(j+1)), theta_j = pi j / H (in double).
double skyRowSolidAngle(uint32_t width, uint32_t height, uint32_t j);
// The unit direction at an elevation and azimuth in degrees (see above).
Vec3 skyDirection(double elevationDegrees, double azimuthDegrees);

// CIE standard overcast sky: L(theta) = Lz (1 + 2 cos theta) / 3 above the
// horizon (theta from the zenith), `ground` below. H must be even (the
// horizon a texel boundary).
struct OvercastParams {
  double Lz = 1.0, ground = 0.0;
};
SkyImage overcastSky(uint32_t width, uint32_t height, const OvercastParams& p);

// L = max(0, a + b w_up) over the whole sphere (w_up = the direction's y).
// The upward irradiance is pi (a + 2b/3) when nothing clamps (a >= |b|).
struct GradientParams {
  double a = 1.0, b = 0.5;
};
SkyImage gradientSky(uint32_t width, uint32_t height, const GradientParams& p);

// Black but for texel (column, row), of radiance L (grey).
SkyImage texelSky(uint32_t width, uint32_t height, uint32_t column, uint32_t row, double L);
// The same for the texel the direction at (elevation, azimuth) falls in
// (EnvironmentView::texelOf's rule).
SkyImage texelSkyAt(uint32_t width, uint32_t height, double elevationDegrees, double azimuthDegrees, double L);
// The texel (column i, row j) the direction at (elevation, azimuth) falls in.
void skyTexelOf(uint32_t width, uint32_t height, double elevationDegrees, double azimuthDegrees, uint32_t& i, uint32_t& j);

// The upper half (rows above the horizon) L, the lower half black. H even.
SkyImage halfSky(uint32_t width, uint32_t height, double L);

// Preetham, Shirley and Smits 1999, "A Practical Analytic Model for
// Daylight" [PSS]: the Perez distribution of luminance Y and chromaticity
// x, y with the coefficients of [PSS Appendix A.2] as functions of the
// turbidity T, normalised so the zenith luminance is Lz, converted xyY ->
// XYZ -> linear Rec.709 (negative components clamped to 0), plus a neutral
// sun disc and a constant ground. H even.
struct SunSkyParams {
  double turbidity = 3.0;
  double elevation = 45.0, azimuth = 0.0;  // the sun, degrees
  double Lz = 1.0;                         // the sky's zenith luminance
  double sunDiameter = 0.53;               // degrees (full angle)
  // Luminance of the sun (grey RGB); NaN: 1e5 x Lz.
  double sunRadiance = std::numeric_limits<double>::quiet_NaN();
  // Grey ground radiance; NaN: 0.1 x the mean sky radiance over the upper
  // hemisphere (per channel, the sun excluded).
  double ground = std::numeric_limits<double>::quiet_NaN();
};
// What a sun sky resolved its defaults to, and the paper's absolute zenith.
struct SunSkyInfo {
  double sunRadiance = 0.0;
  Vec3 ground{0, 0, 0};
  double zenithLuminanceKcd = 0.0;  // [PSS A.2] Y_z in kcd/m^2 (reported, not used)
  double zenithX = 0.0, zenithY = 0.0;  // chromaticity at the zenith
  double sunSolidAngle = 0.0;           // sum of coverage x texel solid angle
};
SkyImage sunSky(uint32_t width, uint32_t height, const SunSkyParams& p, SunSkyInfo* info = nullptr);

// The Perez function F(theta, gamma) = (1 + A e^(B / cos theta)) (1 + C
// e^(D gamma) + E cos^2 gamma) [PSS eq. 3].
struct PerezCoefficients {
  double A = 0, B = 0, C = 0, D = 0, E = 0;
};
double perez(const PerezCoefficients& c, double cosTheta, double gamma);
// [PSS Appendix A.2]: the coefficients of Y, x and y for turbidity T; the
// zenith luminance (kcd/m^2) and chromaticity for a sun at zenith angle
// thetaS (radians).
void preethamCoefficients(double T, PerezCoefficients& Y, PerezCoefficients& x, PerezCoefficients& y);
double preethamZenithLuminance(double T, double thetaS);
void preethamZenithChromaticity(double T, double thetaS, double& x, double& y);
// The sky (no sun disc, no ground) in the unit direction d (d.y >= 0) as
// CIE xyY, Y normalised to p.Lz at the zenith, and as linear Rec.709.
void sunSkyXyY(const SunSkyParams& p, Vec3 d, double& x, double& y, double& Y);
Vec3 sunSkyRadiance(const SunSkyParams& p, Vec3 d);
// CIE xyY -> XYZ -> linear Rec.709 (D65), negative components clamped to 0.
Vec3 xyYToRec709(double x, double y, double Y);

// --- the command ----------------------------------------------------------

// The model names: overcast, gradient, texel, half, sunsky.
const std::vector<std::string>& skyModels();
// A model by name with "key=value" parameters (docs/cli.md "Analytic
// environments"): the map and a one-line description of every parameter as
// used ("overcast Lz=1 ground=0"). Throws obscura::Error naming the model,
// the key or the value.
SkyImage makeSky(const std::string& model, uint32_t width, uint32_t height, const std::vector<std::string>& params,
                 std::string& description);

struct SkyArgs {
  std::string model, output;
  std::string res;  // "" = the model's default (skyDefaultResolution)
  std::vector<std::string> params;
};
// "512x256", or "2048x1024" for sunsky (its 0.53 degree sun covers ~7 texels).
std::string skyDefaultResolution(const std::string& model);
// `obscura sky`: makes the map and writes it (writeRgbExr) with the header
// attributes obscura:sky (the description), obscura:sky:model, obscura:version
// and obscura:upAxis. Returns the exit code.
int runSky(const SkyArgs& args);

}  // namespace obscura
