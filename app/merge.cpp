#include "app/merge.h"
#include "core/util/input_file.h"

#include <obscura/error.h>
#include "core/image/image_io.h"
#include "core/image/oiio_module.h"
#include "app/render_setup.h"

namespace obscura {

// The work is OpenImageIO's (headers compared attribute by attribute, any
// channel layout), so it lives in the module loaded on demand.
void mergeRegions(const std::string& output, const std::vector<std::string>& tiles) {
  if (tiles.empty()) throw Error("merge: no tiles given");
  for (const std::string& t : tiles) checkInputFile(t, "merge: TILE ");
  // Before any work: the output may not be one of the tiles (it would be
  // replaced by the merge of itself and the others), and is written as
  // OpenEXR, so its name says so (as render's -o).
  for (size_t i = 0; i < tiles.size(); ++i)
    if (samePath(output, tiles[i]))
      throw Error("merge: OUT.exr " + output + ": is the same file as TILE " + std::to_string(i + 1) + " " + tiles[i] +
                  "; refusing to overwrite an input");
  if (!hasExtension(output, ".exr")) throw Error("merge: OUT.exr " + output + ": must end in .exr (the merge is written as OpenEXR)");
  checkWritable(output);
  oiioModule(tiles.front()).mergeRegions(output, tiles);
}

}  // namespace obscura
