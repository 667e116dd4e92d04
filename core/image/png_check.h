// A PNG whose header declares more pixels than its file could hold. Readers
// (libpng through OpenImageIO) allocate the image the header declares
// before they meet the end of the data: a 65-byte file claiming 30000 x
// 30000 took 3.6 GB as a height map before its error. Deflate packs at most
// 1032 bytes into one (a 258-byte match in two bits, RFC 1951 3.2.5), so
// the file's size bounds the image it can hold, whatever the budget.
#pragma once

#include <string>

namespace obscura {

// Throws obscura::Error naming `path`, the declared size and the file's
// when `path` is a PNG (by its signature) whose IHDR declares more
// filtered image bytes than 1032 times the file's size. Other files, and
// files it cannot read, pass (their reader reports them).
void checkPngFitsItsFile(const std::string& path);

}  // namespace obscura
