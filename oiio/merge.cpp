#include "app/merge.h"

#include "app/exr_header.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>

#include <obscura/error.h>
#include "core/image/image_io.h"
#include "core/util/memory_budget.h"

namespace obscura {
namespace {

// A tile's header: read first, for every tile, so nothing is read in bulk
// (or written) before all of them are known to fit.
struct TileHeader {
  std::string path;
  OIIO::ImageSpec spec;
};

TileHeader readHeader(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw Error(path + ": cannot open: " + OIIO::geterror());
  TileHeader t{path, in->spec()};
  const std::string format = in->format_name();
  in->close();
  if (format != "openexr") throw Error(path + ": not an OpenEXR file (" + format + ")");
  if (t.spec.get_string_attribute("obscura:resolution").empty())
    throw Error(path + ": not an Obscura render (no obscura:resolution in its header)");
  if (t.spec.depth != 1 || t.spec.deep) throw Error(path + ": not a flat 2D image");
  return t;
}

std::string windowText(int x, int y, int w, int h) {
  return std::to_string(w) + "x" + std::to_string(h) + " at (" + std::to_string(x) + "," + std::to_string(y) + ")";
}

// An attribute's value for a message (long ones, like a manifest, cut).
std::string valueText(const OIIO::ParamValue& p) {
  std::string v = p.get_string(16);
  if (v.size() > 60) v = v.substr(0, 57) + "...";
  return v;
}

bool sameValue(const OIIO::ParamValue& a, const OIIO::ParamValue& b) {
  if (a.type() != b.type() || a.nvalues() != b.nvalues()) return false;
  if (a.type().basetype == OIIO::TypeDesc::STRING) {
    for (int i = 0; i < a.nvalues(); ++i)
      if (a.get_ustring(i) != b.get_ustring(i)) return false;
    return true;
  }
  // Bits, not values: a setting is the same only if stored identically.
  return std::memcmp(a.data(), b.data(), a.datasize()) == 0;
}

// Every attribute but the per-tile ones must be in both headers, equal.
void checkSameHeader(const TileHeader& first, const TileHeader& t) {
  for (const OIIO::ParamValue& p : first.spec.extra_attribs) {
    const std::string name = p.name().string();
    if (isPerTileAttribute(name)) continue;
    const OIIO::ParamValue* q = t.spec.find_attribute(name);
    if (!q) throw Error(t.path + ": header: " + name + " is missing (" + first.path + " has it)");
    if (!sameValue(p, *q))
      throw Error(t.path + ": header: " + name + " is " + valueText(*q) + ", but " + valueText(p) + " in " + first.path +
                  " (not a tile of the same render)");
  }
  for (const OIIO::ParamValue& q : t.spec.extra_attribs) {
    const std::string name = q.name().string();
    if (!isPerTileAttribute(name) && !first.spec.find_attribute(name))
      throw Error(t.path + ": header: " + name + " is not in " + first.path + "'s header (not a tile of the same render)");
  }
}

void checkSameFrameAndChannels(const TileHeader& first, const TileHeader& t) {
  const OIIO::ImageSpec &a = first.spec, &b = t.spec;
  if (a.full_x != b.full_x || a.full_y != b.full_y || a.full_width != b.full_width || a.full_height != b.full_height)
    throw Error(t.path + ": display window " + windowText(b.full_x, b.full_y, b.full_width, b.full_height) + " differs from " +
                first.path + "'s " + windowText(a.full_x, a.full_y, a.full_width, a.full_height));
  if (a.channelnames != b.channelnames) {
    std::string list;
    for (const auto& n : b.channelnames) list += (list.empty() ? "" : ",") + n;
    throw Error(t.path + ": channels " + list + " differ from " + first.path + "'s");
  }
  for (int c = 0; c < a.nchannels; ++c)
    if (a.channelformat(c) != b.channelformat(c))
      throw Error(t.path + ": channel " + b.channelnames[size_t(c)] + " is " + b.channelformat(c).c_str() + ", " +
                  a.channelformat(c).c_str() + " in " + first.path);
}

// The data window, in frame pixels relative to the display window's origin.
struct Rect {
  int x0, y0, x1, y1;
};
Rect dataRect(const OIIO::ImageSpec& s) {
  return {s.x - s.full_x, s.y - s.full_y, s.x - s.full_x + s.width, s.y - s.full_y + s.height};
}

uint64_t parseCount(const TileHeader& t, const std::string& name) {
  const std::string v = t.spec.get_string_attribute(name);
  char* end = nullptr;
  const unsigned long long n = std::strtoull(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0') throw Error(t.path + ": header: " + name + " is not a count ('" + v + "')");
  return n;
}

}  // namespace

// Called through the module table (core/image/oiio_module.h) by app/merge.cpp.
void mergeRegionsOiio(const std::string& output, const std::vector<std::string>& paths) {
  if (paths.empty()) throw Error("merge: no tiles given");
  checkWritable(output);
  std::vector<TileHeader> tiles;
  for (const std::string& p : paths) tiles.push_back(readHeader(p));
  const TileHeader& first = tiles.front();
  const OIIO::ImageSpec& fs = first.spec;
  const int W = fs.full_width, H = fs.full_height;
  for (const TileHeader& t : tiles) {
    if (&t != &first) {
      checkSameFrameAndChannels(first, t);
      checkSameHeader(first, t);
    }
    const Rect r = dataRect(t.spec);
    if (r.x0 < 0 || r.y0 < 0 || r.x1 > W || r.y1 > H)
      throw Error(t.path + ": data window " + windowText(t.spec.x, t.spec.y, t.spec.width, t.spec.height) +
                  " is not inside the display window " + windowText(fs.full_x, fs.full_y, W, H));
  }
  // The frame, the largest tile's pixels and the coverage map, from the
  // headers, before any is allocated (an edited display window of 60000^2
  // would otherwise take its gigabytes first).
  {
    uint64_t largest = 0;
    for (const TileHeader& t : tiles) largest = std::max(largest, uint64_t(t.spec.width) * uint64_t(t.spec.height));
    const uint64_t frame = uint64_t(W) * uint64_t(H);
    requireMemory((frame + largest) * uint64_t(fs.nchannels) * sizeof(float) + frame,
                  first.path + ": display window " + windowText(fs.full_x, fs.full_y, W, H) + ", " +
                      std::to_string(fs.nchannels) + " channels");
  }
  // Each pixel exactly once: no two windows intersect, and their areas add
  // up to the frame's (then they cover it).
  uint64_t area = 0;
  for (size_t i = 0; i < tiles.size(); ++i) {
    const Rect a = dataRect(tiles[i].spec);
    area += uint64_t(a.x1 - a.x0) * uint64_t(a.y1 - a.y0);
    for (size_t j = 0; j < i; ++j) {
      const Rect b = dataRect(tiles[j].spec);
      const int x0 = std::max(a.x0, b.x0), y0 = std::max(a.y0, b.y0);
      if (x0 < std::min(a.x1, b.x1) && y0 < std::min(a.y1, b.y1))
        throw Error(tiles[i].path + ": overlaps " + tiles[j].path + " (both hold pixel (" + std::to_string(x0) + "," +
                    std::to_string(y0) + "))");
    }
  }
  if (area != uint64_t(W) * uint64_t(H)) {
    std::vector<char> covered(size_t(W) * size_t(H), 0);
    for (const TileHeader& t : tiles) {
      const Rect r = dataRect(t.spec);
      for (int y = r.y0; y < r.y1; ++y) std::fill_n(covered.begin() + ptrdiff_t(size_t(y) * W + r.x0), r.x1 - r.x0, 1);
    }
    const size_t gap = size_t(std::find(covered.begin(), covered.end(), 0) - covered.begin());
    throw Error(output + ": the tiles leave " + std::to_string(uint64_t(W) * H - area) + " pixels uncovered, the first (" +
                std::to_string(gap % size_t(W)) + "," + std::to_string(gap / size_t(W)) + ")");
  }

  // The frame's pixels, each tile's rows copied into place.
  const size_t nc = size_t(fs.nchannels);
  std::vector<float> frame(size_t(W) * size_t(H) * nc);
  std::vector<float> px;
  for (const TileHeader& t : tiles) {
    auto in = OIIO::ImageInput::open(t.path);
    if (!in) throw Error(t.path + ": cannot open: " + OIIO::geterror());
    px.resize(size_t(t.spec.width) * size_t(t.spec.height) * nc);
    if (!in->read_image(0, 0, 0, int(nc), OIIO::TypeDesc::FLOAT, px.data()))
      throw Error(t.path + ": cannot read its pixels: " + in->geterror());
    const Rect r = dataRect(t.spec);
    const size_t row = size_t(t.spec.width) * nc;
    for (int y = r.y0; y < r.y1; ++y)
      std::copy_n(px.begin() + ptrdiff_t(size_t(y - r.y0) * row), row,
                  frame.begin() + ptrdiff_t((size_t(y) * size_t(W) + size_t(r.x0)) * nc));
  }

  // The header of the full render: the frame as the data window, the
  // per-tile attributes summed (or dropped) as mergeRegions documents.
  OIIO::ImageSpec spec = fs;
  spec.x = fs.full_x, spec.y = fs.full_y, spec.width = W, spec.height = H;
  spec.attribute("obscura:region", "0,0," + std::to_string(W) + "," + std::to_string(H));
  uint64_t rays[3] = {0, 0, 0};
  float renderTime = 0, bvhTime = 0;
  bool sameThreads = true;
  for (const TileHeader& t : tiles) {
    rays[0] += parseCount(t, "obscura:rays:camera");
    rays[1] += parseCount(t, "obscura:rays:occlusion");
    rays[2] += parseCount(t, "obscura:rays:closest");
    renderTime += t.spec.get_float_attribute("obscura:renderTime");
    bvhTime += t.spec.get_float_attribute("obscura:bvhBuildTime");
    sameThreads = sameThreads && t.spec.get_int_attribute("obscura:threads") == fs.get_int_attribute("obscura:threads");
  }
  spec.attribute("obscura:rays:camera", std::to_string(rays[0]));
  spec.attribute("obscura:rays:occlusion", std::to_string(rays[1]));
  spec.attribute("obscura:rays:closest", std::to_string(rays[2]));
  spec.attribute("obscura:rays:total", std::to_string(rays[0] + rays[1] + rays[2]));
  spec.attribute("obscura:renderTime", renderTime);
  spec.attribute("obscura:bvhBuildTime", bvhTime);
  if (!sameThreads) spec.erase_attribute("obscura:threads");
  spec.erase_attribute("obscura:checkpointRuns");  // a tile's own history, not the frame's
  spec.erase_attribute("DateTime");  // the merged file's own (OpenImageIO stamps it)

  OutputSet out;
  out.addFile(output, [&](const std::string& tmp) {
    auto o = OIIO::ImageOutput::create("openexr");
    if (!o) throw Error(output + ": OpenImageIO has no 'openexr' writer: " + OIIO::geterror());
    if (!o->open(tmp, spec)) throw Error(output + ": cannot open for writing: " + o->geterror());
    const bool ok = o->write_image(OIIO::TypeDesc::FLOAT, frame.data());
    std::string e = ok ? "" : o->geterror();
    const bool closed = o->close();
    if (ok && !closed) e = o->geterror();
    if (!ok || !closed) throw Error(output + ": write failed: " + e);
  });
  out.commit();
}

}  // namespace obscura
