// Inputs that are not regular files. Every file Obscura reads - the scene,
// its buffers and images, an OBJ's material libraries, height and
// environment maps, references, tiles, checkpoints, fit coefficients - is
// read to its end or by its size, so a FIFO blocks forever, /dev/zero never
// ends (a reader that grows its buffer takes all memory) and a directory
// reads as garbage. Each is refused by name before it is opened.
#pragma once

#include <string>

namespace obscura {

// "" when `path` is a regular file (after symbolic links) or does not exist
// (the caller reports a missing file in its own words), else what it is:
// "a FIFO", "a character device", "a block device", "a directory", "a socket".
std::string nonRegularKind(const std::string& path);

// Throws obscura::Error "`what``path`: is a FIFO, not a regular file" when
// nonRegularKind(path) is not empty. `what` prefixes the message (an option
// name and a space, e.g. "--displace "), may be empty.
void checkInputFile(const std::string& path, const std::string& what = "");

}  // namespace obscura
