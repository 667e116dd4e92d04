#include "app/merge.h"

#include <obscura/error.h>
#include "core/image/oiio_module.h"

namespace obscura {

// The work is OpenImageIO's (headers compared attribute by attribute, any
// channel layout), so it lives in the module loaded on demand.
void mergeRegions(const std::string& output, const std::vector<std::string>& tiles) {
  if (tiles.empty()) throw Error("merge: no tiles given");
  oiioModule(tiles.front()).mergeRegions(output, tiles);
}

}  // namespace obscura
