// The environment a render is lit by (docs/math.md §14): a uniform sky or
// an equirectangular map, owned here and read by integrators through
// EnvironmentView (include/obscura/environment.h).
//
// Built once per render: the map (strength applied), the sampling CDFs of
// its luminance times solid angle, and the unoccluded irradiance E0(n)/pi
// - by the exact convolution into a lat-long table of normals (the
// default), or by nine spherical-harmonic coefficients - with the SH
// approximation's error against the exact table measured either way.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <obscura/environment.h>
#include <obscura/large_vector.h>

namespace obscura {

enum class IrradianceMethod { Exact, Sh9 };
// "exact" / "sh9"; throws obscura::Error naming `what` for anything else.
IrradianceMethod irradianceMethodFromName(const std::string& name, const std::string& what);
const char* irradianceMethodName(IrradianceMethod m);

struct EnvironmentOptions {
  std::string path;               // "" = the constant sky
  double rotationDegrees = 0.0;   // about +Y, right-handed
  double strength = 1.0;          // multiplies every texel
  IrradianceMethod irradiance = IrradianceMethod::Exact;
};

// The error of E0 by nine SH coefficients against the exact convolution,
// over the irradiance table's normals (luminance, solid-angle weighted):
// the largest and the RMS difference, both relative to the mean E0.
struct Sh9Error {
  double max = 0.0, rms = 0.0;
};

class Environment {
 public:
  // The uniform sky of radiance L (finite, >= 0).
  static std::shared_ptr<const Environment> constant(Vec3 L);
  // An equirectangular map from a file any reader of ours reads (EXR
  // directly, other formats through OpenImageIO; 8-bit sRGB files are
  // decoded to linear). Throws obscura::Error naming the file, and the
  // texel for a NaN, infinite or negative value.
  static std::shared_ptr<const Environment> load(const EnvironmentOptions& options);
  // A map from RGB texels (top row first): tests and the sky generator.
  // `name` stands in for the path in messages.
  static std::shared_ptr<const Environment> fromTexels(std::vector<float> rgb, uint32_t width, uint32_t height,
                                                       const EnvironmentOptions& options, const std::string& name);

  const EnvironmentView& view() const { return view_; }
  bool isConstant() const { return view_.constant; }
  Vec3 meanRadiance() const { return view_.meanRadiance; }
  uint32_t width() const { return view_.width; }
  uint32_t height() const { return view_.height; }
  const EnvironmentOptions& options() const { return options_; }
  // FNV-1a 64 of the texels as read (before the strength), hex: what the
  // EXR header records, so a re-encoded file with the same values matches.
  const std::string& contentHash() const { return hash_; }
  const Sh9Error& sh9Error() const { return shError_; }
  // E0(n)/pi by the exact convolution at a map-frame direction (slow: the
  // table's nodes are built from it; tests compare against it).
  Vec3 exactIrradianceOverPi(Vec3 mapDirection) const;
  // E0(n)/pi from the SH coefficients at a map-frame direction.
  Vec3 sh9IrradianceOverPi(Vec3 mapDirection) const;

  Environment(const Environment&) = delete;
  Environment& operator=(const Environment&) = delete;
  ~Environment();

  // The irradiance table's size (nodes): fixed, docs/math.md §14.4.
  static constexpr uint32_t kIrradianceWidth = 128, kIrradianceHeight = 65;

 private:
  Environment() = default;
  void build(std::vector<float> rgb, uint32_t width, uint32_t height, const std::string& name);
  void buildSampling();
  void buildPyramid();
  void buildIrradiance();

  struct Pyramid;
  EnvironmentOptions options_;
  // The tables a light draw or a lookup reads at random (tens of MiB for a
  // 2048 x 1024 map) on huge pages: a random read through 4 KiB pages
  // misses the TLB as well as the caches (docs/math.md §14.3, "Cost").
  LargeVector<float> texels_, columnCdf_;
  LargeVector<uint32_t> columnGuide_;
  std::vector<float> rowCdf_, rowSolidAngle_, rowCos_, irradiance_;
  std::vector<uint32_t> rowGuide_;
  std::unique_ptr<Pyramid> pyramid_;
  EnvironmentView view_;
  std::string hash_;
  Sh9Error shError_;
};

}  // namespace obscura
