// The paths of this build (tests/support.h): the only test file whose
// compile definitions name the clone (tests/CMakeLists.txt).
#include <string>

#include "tests/support.h"

namespace obscura::test {

const char* sourceDir() { return OBSCURA_SOURCE_DIR; }
const char* obscuraBinary() { return OBSCURA_BINARY; }
const char* defaultScenesDir() { return OBSCURA_DEFAULT_SCENES; }
std::string sourcePath(const std::string& rel) { return std::string(sourceDir()) + "/" + rel; }

}  // namespace obscura::test
