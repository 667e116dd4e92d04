#include "core/util/input_file.h"

#include <sys/stat.h>

#include <obscura/error.h>

namespace obscura {

std::string nonRegularKind(const std::string& path) {
  struct stat st {};
  // stat, not open: opening a FIFO for reading blocks until a writer comes.
  if (::stat(path.c_str(), &st) != 0) return "";
  if (S_ISREG(st.st_mode)) return "";
  if (S_ISFIFO(st.st_mode)) return "a FIFO";
  if (S_ISCHR(st.st_mode)) return "a character device";
  if (S_ISBLK(st.st_mode)) return "a block device";
  if (S_ISDIR(st.st_mode)) return "a directory";
  if (S_ISSOCK(st.st_mode)) return "a socket";
  return "not a file";
}

void checkInputFile(const std::string& path, const std::string& what) {
  const std::string kind = nonRegularKind(path);
  if (!kind.empty()) throw Error(what + path + ": is " + kind + ", not a regular file");
}

}  // namespace obscura
