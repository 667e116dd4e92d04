// `obscura merge OUT.exr TILES...`: region renders (`render --region`)
// assembled into the full frame (docs/production.md "Regions and merging").
#pragma once

#include <string>
#include <vector>

namespace obscura {

// Checks that `tiles` belong to one render - the same header but for the
// per-tile attributes (isPerTileAttribute, app/exr_header.h), the same display window and channels (names and
// pixel types) - and cover its frame exactly once, then writes their pixels
// as one EXR whose data window is the frame: bit for bit the single full
// render. Its header is the tiles' with obscura:region the frame, the ray
// counts, renderTime and bvhBuildTime summed over the tiles, and
// obscura:threads kept if every tile has the same, else dropped, and
// DateTime the time of the merge. Throws
// obscura::Error "FILE: why" naming the first tile that does not fit (or
// OUT for a gap); OUT is written atomically and only when every check
// passed. Reads and writes through OpenImageIO, in libobscura_oiio.so
// (oiio/merge.cpp; core/image/oiio_module.h).
void mergeRegions(const std::string& output, const std::vector<std::string>& tiles);

}  // namespace obscura
