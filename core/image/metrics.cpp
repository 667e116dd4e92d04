#include "core/image/metrics.h"
#include "core/util/memory_budget.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <algorithm>
#include <cmath>

#include <obscura/error.h>
#include "core/image/flip.h"
#include "core/image/image_io.h"
#include "core/image/oiio_module.h"

namespace obscura {

float PassImage::W(int c, size_t i) const {
  const float alpha = a[i];
  if (!(alpha > 0.0f)) return 0.0f;
  const float v = c == 0 ? r[i] : c == 1 ? g[i] : b[i];
  return v / alpha;
}

PassImage passFromFilm(const Film& film) {
  PassImage p;
  p.width = film.width();
  p.height = film.height();
  const size_t n = p.pixels();
  p.r.assign(film.plane(kR), film.plane(kR) + n);
  p.g.assign(film.plane(kG), film.plane(kG) + n);
  p.b.assign(film.plane(kB), film.plane(kB) + n);
  p.a.assign(film.plane(kA), film.plane(kA) + n);
  return p;
}

PassImage shadedFromFilm(const Film& film) {
  PassImage p = passFromFilm(film);
  if (!film.hasAlbedo()) throw Error("the film has no shaded.* channels (no albedo AOV)");
  const size_t n = p.pixels();
  p.r.assign(film.plane(kShadedR), film.plane(kShadedR) + n);
  p.g.assign(film.plane(kShadedG), film.plane(kShadedG) + n);
  p.b.assign(film.plane(kShadedB), film.plane(kShadedB) + n);
  return p;
}

void scaleRgb(PassImage& p, double s) {
  for (std::vector<float>* plane : {&p.r, &p.g, &p.b})
    for (float& v : *plane) v = float(double(v) * s);
}

double meanCoveredRgb(const PassImage& p) {
  double sum = 0;
  size_t n = 0;
  for (size_t i = 0; i < p.pixels(); ++i)
    if (p.a[i] == 1.0f) sum += double(p.r[i]) + p.g[i] + p.b[i], n += 3;
  return n ? sum / double(n) : 0.0;
}

PassImage readPass(const std::string& path) {
  // An EXR through OpenEXR (no OpenImageIO start-up); other formats through
  // the module (core/image/oiio_module.h).
  if (!isExrFile(path)) return oiioModule(path).readPass(path);
  return readPass(path, "");
}

PassImage readPass(const std::string& path, const std::string& prefix) {
  if (!isExrFile(path)) throw Error(path + ": not an OpenEXR file (" + prefix + "R/G/B are read from EXR only)");
  PassImage p;
  const std::string r = prefix + "R", g = prefix + "G", b = prefix + "B";
  const char* names[4] = {r.c_str(), g.c_str(), b.c_str(), "A"};
  try {
    Imf::InputFile in(path.c_str());
    const Imath::Box2i data = in.header().dataWindow();
    p.width = data.max.x - data.min.x + 1;
    p.height = data.max.y - data.min.y + 1;
    requireMemory(uint64_t(p.width) * uint64_t(p.height) * 4 * sizeof(float),
                  path + ": data window " + std::to_string(p.width) + "x" + std::to_string(p.height));
    std::vector<float>* planes[4] = {&p.r, &p.g, &p.b, &p.a};
    Imf::FrameBuffer frame;
    for (int c = 0; c < 4; ++c) {
      if (!in.header().channels().findChannel(names[c]))
        throw Error(path + ": channel " + names[c] + " is missing (not an obscura pass?)");
      planes[c]->resize(p.pixels());
      frame.insert(names[c], Imf::Slice::Make(Imf::FLOAT, planes[c]->data(), data, sizeof(float),
                                              size_t(p.width) * sizeof(float)));
    }
    in.setFrameBuffer(frame);
    in.readPixels(data.min.y, data.max.y);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(path + ": cannot read: " + e.what());
  }
  return p;
}

std::vector<size_t> comparedPixels(const PassImage& test, const PassImage& ref) {
  if (test.width != ref.width || test.height != ref.height)
    throw Error("image sizes differ: " + std::to_string(test.width) + "x" + std::to_string(test.height) + " vs reference " +
                std::to_string(ref.width) + "x" + std::to_string(ref.height));
  std::vector<size_t> idx;
  for (size_t i = 0; i < ref.pixels(); ++i)
    if (ref.a[i] == 1.0f && test.a[i] > 0.0f) idx.push_back(i);
  if (idx.empty()) throw Error("no pixel is covered by both the pass and the reference");
  return idx;
}

ErrorMetrics errorMetrics(const PassImage& test, const PassImage& ref) {
  const std::vector<size_t> idx = comparedPixels(test, ref);
  ErrorMetrics m;
  std::vector<double> absErr;
  absErr.reserve(idx.size() * 3);
  double se = 0, rel = 0, ae = 0;
  for (const size_t i : idx)
    for (int c = 0; c < 3; ++c) {
      const double w = ref.W(c, i);
      const double e = double(test.W(c, i)) - w;
      se += e * e;
      rel += e * e / (w * w + kRelMseEpsilon);
      ae += std::abs(e);
      absErr.push_back(std::abs(e));
    }
  const double n = double(absErr.size());
  m.values = absErr.size();
  m.rmse = std::sqrt(se / n);
  m.relMse = rel / n;
  m.mae = ae / n;
  // Nearest rank: the smallest value with at least 99% of values <= it.
  const size_t rank = size_t(std::ceil(0.99 * n));
  std::nth_element(absErr.begin(), absErr.begin() + long(rank - 1), absErr.end());
  m.p99 = absErr[rank - 1];
  return m;
}

namespace {
FlipImage flipImageOf(const PassImage& p, bool clampToUnit) {
  FlipImage f;
  f.width = p.width, f.height = p.height;
  f.r = p.r, f.g = p.g, f.b = p.b;
  if (clampToUnit)
    for (std::vector<float>* plane : {&f.r, &f.g, &f.b})
      for (float& v : *plane) v = std::clamp(std::isfinite(v) ? v : 0.0f, 0.0f, 1.0f);
  return f;
}
}  // namespace

FlipError flipError(const PassImage& test, const PassImage& ref, double ppd, bool maps) {
  const std::vector<size_t> idx = comparedPixels(test, ref);
  FlipError e;
  const FlipImage refHdr = flipImageOf(ref, false);
  std::vector<float> ldr = ldrFlip(flipImageOf(ref, true), flipImageOf(test, true), ppd);
  std::vector<float> hdr = hdrFlip(refHdr, flipImageOf(test, false), flipExposures(refHdr, &idx), ppd);
  for (const size_t i : idx) e.ldr += ldr[i], e.hdr += hdr[i];
  e.ldr /= double(idx.size()), e.hdr /= double(idx.size());
  if (maps) {
    e.ldrMap.assign(ldr.size(), 0.0f), e.hdrMap.assign(hdr.size(), 0.0f);
    for (const size_t i : idx) e.ldrMap[i] = ldr[i], e.hdrMap[i] = hdr[i];
  }
  return e;
}

BiasVariance biasVariance(const std::vector<PassImage>& renders, const PassImage& ref, double refNoise) {
  if (renders.size() < 2) throw Error("bias and variance need at least two renders");
  const std::vector<size_t> idx = comparedPixels(renders[0], ref);
  const double K = double(renders.size());
  double var = 0, dev2 = 0;
  size_t n = 0;
  for (const size_t i : idx) {
    bool all = true;
    for (const PassImage& p : renders) all = all && p.a[i] > 0.0f;
    if (!all) continue;
    for (int c = 0; c < 3; ++c) {
      double m = 0;
      for (const PassImage& p : renders) m += p.W(c, i);
      m /= K;
      double s = 0;
      for (const PassImage& p : renders) s += (p.W(c, i) - m) * (p.W(c, i) - m);
      var += s / (K - 1);
      dev2 += (m - ref.W(c, i)) * (m - ref.W(c, i));
      ++n;
    }
  }
  if (n == 0) throw Error("no pixel is covered by every render and the reference");
  BiasVariance bv;
  bv.variance = var / double(n);
  bv.bias2 = dev2 / double(n) - bv.variance / K - refNoise * refNoise;
  return bv;
}

PassImage averagePasses(const PassImage& a, const PassImage& b) {
  PassImage m = a;
  for (size_t i = 0; i < m.pixels(); ++i) {
    m.r[i] = 0.5f * (a.r[i] + b.r[i]);
    m.g[i] = 0.5f * (a.g[i] + b.g[i]);
    m.b[i] = 0.5f * (a.b[i] + b.b[i]);
    m.a[i] = 0.5f * (a.a[i] + b.a[i]);
  }
  return m;
}

double referenceNoise(const PassImage& a, const PassImage& b) {
  const std::vector<size_t> idx = comparedPixels(a, b);
  double s = 0;
  size_t n = 0;
  for (const size_t i : idx) {
    if (a.a[i] != 1.0f) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = double(a.W(c, i)) - b.W(c, i);
      s += d * d / 4.0;
      ++n;
    }
  }
  return n ? std::sqrt(s / double(n)) : 0.0;
}

}  // namespace obscura
