#include "core/image/image_io.h"
#include "core/util/memory_budget.h"
#include "core/util/input_file.h"

#include "core/util/large_vector.h"

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfChromaticitiesAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>
#include <stb_image_write.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cinttypes>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <set>
#include <stdexcept>
#include <thread>
#include <ctime>
#include <filesystem>

#include <obscura/error.h>
#include "core/image/oiio_module.h"
#include "core/image/texture.h"

namespace obscura {
namespace fs = std::filesystem;
namespace {

// Temporary sibling of `path` (same directory, so rename is atomic); `tag`
// tells a backup from a new file.
std::string siblingPath(const std::string& path, const char* tag) {
  const fs::path p(path);
  const std::string name = "." + p.filename().string() + tag + std::to_string(getpid());
  return (p.parent_path() / name).string();
}

// Removes the temporaries and backups of `path` (".NAME.tmpPID",
// ".NAME.bakPID") whose process no longer runs on this host: left by a
// process killed while writing or committing (SIGKILL, an OOM kill, a power
// cut), each as large as the output. A PID that runs again in an unrelated
// process keeps its file until that process ends; a writer on another host
// sharing the directory could lose its temporary to this (its commit then
// fails naming the file, nothing is lost silently): docs/production.md
// "Outputs".
void removeStaleTemporaries(const std::string& path) {
  const fs::path p(path);
  const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  const std::string stem = "." + p.filename().string();
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= stem.size() + 4 || name.compare(0, stem.size(), stem) != 0) continue;
    const std::string tag = name.substr(stem.size(), 4), digits = name.substr(stem.size() + 4);
    if ((tag != ".tmp" && tag != ".bak") || digits.size() > 10 || digits.find_first_not_of("0123456789") != std::string::npos)
      continue;
    const long pid = std::stol(digits);
    if (pid <= 0 || pid == long(getpid()) || ::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;
    std::error_code ignored;
    fs::remove(it->path(), ignored);
  }
}

// OBSCURA_TEST_COMMIT (tests only): "kill" makes OutputSet::commit send the
// process SIGKILL before its first rename (the temporaries written, as a kill
// during the write leaves them); "pause:SECONDS" sleeps after the first
// rename (a commit caught half done).
struct CommitHook {
  bool kill = false;
  double pause = 0;
};
CommitHook commitHook() {
  CommitHook h;
  if (const char* v = std::getenv("OBSCURA_TEST_COMMIT"); v && *v) {
    if (std::strcmp(v, "kill") == 0) h.kill = true;
    else if (std::strncmp(v, "pause:", 6) == 0) h.pause = std::strtod(v + 6, nullptr);
  }
  return h;
}

// Exclusive flock()s on the directories of a commit's destinations, taken
// in one order (by device and inode) and held while the files are moved:
// two processes writing the same pass and preview each land both files, one
// set after the other, never one process's EXR beside the other's PNG. A
// file system without flock on directories goes without (each move is
// still atomic).
class DirectoryLocks {
 public:
  explicit DirectoryLocks(const std::vector<std::string>& dests) {
    std::set<std::pair<std::pair<dev_t, ino_t>, std::string>> dirs;
    for (const std::string& d : dests) {
      const fs::path p = fs::path(d).parent_path().empty() ? fs::path(".") : fs::path(d).parent_path();
      struct stat st {};
      if (::stat(p.c_str(), &st) == 0) dirs.insert({{st.st_dev, st.st_ino}, p.string()});
    }
    for (const auto& [id, dir] : dirs) {
      const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
      if (fd < 0) continue;
      while (::flock(fd, LOCK_EX) != 0 && errno == EINTR) {
      }
      fds_.push_back(fd);
    }
  }
  ~DirectoryLocks() {
    for (int fd : fds_) ::close(fd);  // releases the lock
  }
  DirectoryLocks(const DirectoryLocks&) = delete;
  DirectoryLocks& operator=(const DirectoryLocks&) = delete;

 private:
  std::vector<int> fds_;
};

constexpr std::pair<ExrCompression, Imf::Compression> kCompressions[] = {
    {ExrCompression::None, Imf::NO_COMPRESSION}, {ExrCompression::Rle, Imf::RLE_COMPRESSION},
    {ExrCompression::Zips, Imf::ZIPS_COMPRESSION}, {ExrCompression::Zip, Imf::ZIP_COMPRESSION},
    {ExrCompression::Piz, Imf::PIZ_COMPRESSION}};
constexpr const char* kCompressionNames[] = {"none", "rle", "zips", "zip", "piz"};

// The local time as the EXR standard `capDate` wants it (ImfStandardAttributes.h).
std::string captureDate() {
  const std::time_t now = std::time(nullptr);
  std::tm t{};
  localtime_r(&now, &t);
  char text[32];
  std::strftime(text, sizeof text, "%Y:%m:%d %H:%M:%S", &t);
  return text;
}

// The header attributes every EXR of ours carries, then `attributes`.
void insertHeaderAttributes(Imf::Header& header, const std::vector<HeaderAttribute>& attributes) {
  // CIE xy of the Rec.709 / sRGB primaries R, G, B and of the D65 white
  // (ITU-R BT.709): what linear sRGB textures and a grey sky make.
  header.insert("chromaticities", Imf::ChromaticitiesAttribute(Imf::Chromaticities(
                                      {0.64f, 0.33f}, {0.30f, 0.60f}, {0.15f, 0.06f}, {0.3127f, 0.3290f})));
  header.insert("capDate", Imf::StringAttribute(captureDate()));
  for (const HeaderAttribute& a : attributes) {
    if (auto* s = std::get_if<std::string>(&a.value)) header.insert(a.name, Imf::StringAttribute(*s));
    else if (auto* i = std::get_if<int>(&a.value)) header.insert(a.name, Imf::IntAttribute(*i));
    else if (auto* f = std::get_if<float>(&a.value)) header.insert(a.name, Imf::FloatAttribute(*f));
    else {
      const auto& m = std::get<std::vector<float>>(a.value);
      if (m.size() == 16)
        header.insert(a.name, Imf::M44fAttribute(Imath::M44f(m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9],
                                                              m[10], m[11], m[12], m[13], m[14], m[15])));
    }
  }
}

// The EXR's bytes to a new file, every write checked, the last ones too.
// OpenEXR's own file stream (an std::ofstream) is flushed and closed by
// ~OutputFile, which also writes the line-offset table there and swallows
// any error: a disk that filled at that point left a truncated EXR that was
// renamed over the good one, exit 0. Here the writes go through a buffer of
// our own; an error there (even inside ~OutputFile) is kept and finish()
// reports it, after the last bytes and the close.
class CheckedExrStream : public Imf::OStream {
 public:
  explicit CheckedExrStream(const std::string& tmp) : Imf::OStream(tmp.c_str()) {
    fd_ = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) throw std::runtime_error(std::strerror(errno));
  }
  ~CheckedExrStream() override {
    if (fd_ >= 0) ::close(fd_);
  }
  void write(const char c[], int n) override {
    if (pos_ != start_ + buf_.size()) flush(), start_ = pos_;
    buf_.insert(buf_.end(), c, c + n);
    pos_ += uint64_t(n);
    if (buf_.size() >= (1u << 20)) flush(), start_ = pos_;
    if (err_) throw std::runtime_error(std::strerror(err_));
  }
  uint64_t tellp() override { return pos_; }
  void seekp(uint64_t pos) override { pos_ = pos; }
  // After the OutputFile is gone: the buffered bytes and the close; 0 or
  // the first errno.
  int finish() {
    flush();
    if (::close(fd_) != 0 && !err_) err_ = errno;
    fd_ = -1;
    return err_;
  }

 private:
  void flush() {
    for (size_t done = 0; done < buf_.size() && !err_;) {
      const ssize_t n = ::pwrite(fd_, buf_.data() + done, buf_.size() - done, off_t(start_ + done));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) err_ = n < 0 ? errno : EIO;
      else done += size_t(n);
    }
    buf_.clear();
  }
  int fd_ = -1, err_ = 0;
  std::vector<char> buf_;
  uint64_t start_ = 0, pos_ = 0;  // buf_[0]'s offset in the file; where the next write goes
};

// Runs `write` on an OutputFile over a CheckedExrStream to `tmp`, then
// checks the last bytes and the close; on any failure removes `tmp` and
// throws naming `path`.
void writeExrChecked(const std::string& path, const std::string& tmp, const Imf::Header& header,
                     const std::function<void(Imf::OutputFile&)>& write) {
  int err = 0;
  try {
    CheckedExrStream stream(tmp);
    {
      Imf::OutputFile file(stream, header);
      write(file);
    }  // ~OutputFile: the line-offset table (errors kept by the stream)
    err = stream.finish();
  } catch (const std::exception& e) {
    std::remove(tmp.c_str());
    throw Error(path + ": write failed: " + e.what());
  }
  if (err) {
    std::remove(tmp.c_str());
    throw Error(path + ": write failed: " + std::strerror(err));
  }
}

// Writes the film's channels to `tmp` as a scanline EXR, straight from the
// planes (one slice per plane, no interleaved copy); OpenEXR converts
// float to half per channel and compresses blocks on its thread pool.
void writeExrFile(const std::string& path, const std::string& tmp, const Film& film, const ExrOptions& options) {
  checkWritable(path);
  const std::vector<int>& chans = film.channels();
  // The data window is the film's window, the display window the frame
  // (equal but for a --region render; docs/production.md "Regions and merging").
  const Imath::Box2i data({film.originX(), film.originY()},
                          {film.originX() + film.width() - 1, film.originY() + film.height() - 1});
  const Imath::Box2i display({0, 0}, {film.fullWidth() - 1, film.fullHeight() - 1});
  Imf::Header header(display, data);
  for (const auto& [ours, theirs] : kCompressions)
    if (ours == options.compression) header.compression() = theirs;
  if (options.zipLevel > 0) header.zipCompressionLevel() = options.zipLevel;
  for (int c : chans) {
    const std::string& n = film.name(c);
    const bool keep = !options.half ||
                      (c < kChannelCount ? exrKeepsFloat(c)
                                         : std::any_of(options.floatChannelPrefixes.begin(), options.floatChannelPrefixes.end(),
                                                       [&](const std::string& p) { return n.compare(0, p.size(), p) == 0; }));
    header.channels().insert(n, Imf::Channel(keep ? Imf::FLOAT : Imf::HALF));
  }
  insertHeaderAttributes(header, options.attributes);
  // Float channels are written from the planes in place. OpenEXR's output
  // does not convert, so half channels go through a buffer of `band` rows
  // (a multiple of every block height: 16 for ZIP, 32 for PIZ), converted
  // band by band: never a second copy of the film.
  const size_t w = size_t(film.width());
  std::vector<int> halves;
  for (int c : chans)
    if (header.channels().findChannel(film.name(c))->type == Imf::HALF) halves.push_back(c);
  const int band = halves.empty() ? film.height() : std::min(film.height(), 128);
  std::vector<Imath::half> halfRows(halves.size() * w * size_t(band));
  const auto frameFor = [&](int y0) {  // the slices for rows [y0, y0 + band) of the window
    Imf::FrameBuffer frame;
    for (int c : chans)
      if (std::find(halves.begin(), halves.end(), c) == halves.end())
        frame.insert(film.name(c), Imf::Slice::Make(Imf::FLOAT, film.plane(c), data, sizeof(float), w * sizeof(float)));
    for (size_t k = 0; k < halves.size(); ++k)
      frame.insert(film.name(halves[k]),
                   Imf::Slice::Make(Imf::HALF, halfRows.data() + k * w * size_t(band),
                                    Imath::V2i(film.originX(), film.originY() + y0), int64_t(w), band,
                                    sizeof(Imath::half), w * sizeof(Imath::half)));
    return frame;
  };
  // Compression runs on OpenEXR's own pool, sized like the render's; an
  // image of one block of scanlines (32 for PIZ, 16 for ZIP) has nothing to
  // share, so it starts no thread.
  int threads = options.threads > 0 ? options.threads
                                    : int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  if (film.height() <= 32) threads = 0;
  if (Imf::globalThreadCount() != threads) Imf::setGlobalThreadCount(threads);
  writeExrChecked(path, tmp, header, [&](Imf::OutputFile& file) {
    for (int y0 = 0; y0 < film.height(); y0 += band) {
      const int rows = std::min(band, film.height() - y0);
      for (size_t k = 0; k < halves.size(); ++k) {
        const float* src = film.plane(halves[k]) + size_t(y0) * w;
        Imath::half* dst = halfRows.data() + k * w * size_t(band);
        for (size_t i = 0; i < size_t(rows) * w; ++i) dst[i] = Imath::half(src[i]);
      }
      file.setFrameBuffer(frameFor(y0));
      file.writePixels(rows);
    }
  });
}

// Writes `size` bytes to a new file `tmp`, checking every write and the
// close (a full disk, a file-size limit, a quota), or throws naming `path`
// with the temporary removed.
void writeBytesFile(const std::string& path, const std::string& tmp, const void* data, size_t size) {
  checkWritable(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(path + ": write failed: " + std::strerror(errno));
  const char* bytes = static_cast<const char*>(data);
  int err = 0;
  for (size_t done = 0; done < size && !err;) {
    const ssize_t n = ::write(fd, bytes + done, size - done);
    if (n > 0) done += size_t(n);
    else if (n == 0) err = EIO;
    else if (errno != EINTR) err = errno;
  }
  if (::close(fd) != 0 && !err) err = errno;
  if (err) {
    ::unlink(tmp.c_str());
    throw Error(path + ": write failed: " + std::strerror(err));
  }
}

// CRC-32 of PNG chunks (PNG specification, 5.5 "CRC algorithm": the
// reflected polynomial 0xEDB88320, register preset to all ones, result
// complemented), over the chunk type and data.
uint32_t pngCrc(const unsigned char* bytes, size_t n) {
  static const auto table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  uint32_t c = 0xFFFFFFFFu;
  for (size_t i = 0; i < n; ++i) c = table[(c ^ bytes[i]) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

void appendBigEndian32(std::string& out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(char((v >> shift) & 0xFF));
}

// One PNG chunk: length, type, data, CRC of type and data.
void appendPngChunk(std::string& out, const char type[4], const std::vector<uint32_t>& data32, const std::string& data8) {
  std::string body(type, 4);
  for (uint32_t v : data32) appendBigEndian32(body, v);
  body += data8;
  appendBigEndian32(out, uint32_t(body.size() - 4));
  out += body;
  appendBigEndian32(out, pngCrc(reinterpret_cast<const unsigned char*>(body.data()), body.size()));
}

// stb_image_write writes no colour-space chunk, so a viewer or compositor
// had to guess what the bytes mean (issue #37). They are sRGB-encoded
// (linearToSrgb8), so after IHDR: sRGB (rendering intent 0, perceptual) and,
// as the PNG specification (11.3.3.5 "sRGB") recommends for decoders that
// do not know sRGB, the gAMA and cHRM it implies: gamma 1/2.2 as 45455, and
// the Rec.709 primaries with a D65 white, times 100000.
std::string tagSrgb(const std::string& png) {
  constexpr size_t kIhdrEnd = 8 + 4 + 4 + 13 + 4;  // signature, then IHDR's length, type, 13 bytes, CRC
  if (png.size() < kIhdrEnd || png.compare(12, 4, "IHDR") != 0) throw Error("PNG encoder: no IHDR chunk first");
  std::string out = png.substr(0, kIhdrEnd);
  appendPngChunk(out, "cHRM", {31270, 32900, 64000, 33000, 30000, 60000, 15000, 6000}, "");
  appendPngChunk(out, "gAMA", {45455}, "");
  appendPngChunk(out, "sRGB", {}, std::string(1, '\0'));
  out.append(png, kIhdrEnd, std::string::npos);
  return out;
}

// Encodes in memory, then writes through writeBytesFile: stbi_write_png
// itself ignores what fwrite and fclose return, so a full disk left a
// truncated PNG that was then moved over the previous one.
void writePngFile(const std::string& path, const std::string& tmp, int width, int height, const unsigned char* rgb) {
  checkWritable(path);
  std::string png;
  const auto append = [](void* context, void* data, int size) {
    static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
  };
  if (!stbi_write_png_to_func(append, &png, width, height, 3, rgb, width * 3))
    throw Error(path + ": write failed: cannot encode the image");
  const std::string tagged = tagSrgb(png);
  writeBytesFile(path, tmp, tagged.data(), tagged.size());
}

std::vector<unsigned char> previewPixels(const Film& film) {
  const int w = film.width(), h = film.height();
  std::vector<unsigned char> px(size_t(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) px[(size_t(y) * w + x) * 3 + c] = linearToSrgb8(film.plane(kR + c)[size_t(y) * w + x]);
  return px;
}

}  // namespace

bool exrKeepsFloat(int channel) { return channel == kNX || channel == kNY || channel == kNZ || channel == kZ; }

void checkOutputName(const std::string& path, const std::string& what, size_t extra) {
  const fs::path p(path);
  const fs::path parent = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  const long max = ::pathconf(parent.c_str(), _PC_NAME_MAX);
  const size_t limit = max > 0 ? size_t(max) : 255, name = p.filename().string().size();
  if (name + extra > limit)
    throw Error(what + path + ": the file name is " + std::to_string(name) + " bytes; at most " +
                std::to_string(limit > extra ? limit - extra : 0) + " fit (the file system's limit of " +
                std::to_string(limit) + " bytes, less " + std::to_string(extra) + " for the temporary written beside it)");
}

void checkWritable(const std::string& path) {
  const fs::path p(path);
  const fs::path parent = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  std::error_code ec;
  if (!fs::is_directory(parent, ec))
    throw Error(path + ": cannot write: directory '" + parent.string() + "' does not exist");
  if (fs::is_directory(p, ec)) throw Error(path + ": cannot write: it is a directory");
  if (::access(parent.c_str(), W_OK | X_OK) != 0)
    throw Error(path + ": cannot write: directory '" + parent.string() + "' is not writable");
  checkOutputName(path, "");
}

uint64_t filmBytes(int width, int height, bool aovs, bool albedo) {
  // With the AOVs, the fixed channels (but albedo.* and shaded.* without
  // the albedo AOV) and the W_error and spp planes.
  const uint64_t planes = !aovs ? 4 : kChannelCount + 2 - (albedo ? 0 : 6);
  return uint64_t(std::max(width, 0)) * uint64_t(std::max(height, 0)) * planes * sizeof(float);
}

uint64_t availableMemoryBytes() {
  std::FILE* f = std::fopen("/proc/meminfo", "r");
  if (!f) return 0;
  char line[256];
  uint64_t kib = 0;
  while (std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "MemAvailable: %" SCNu64 " kB", &kib) == 1) break;
  std::fclose(f);
  if (kib == 0) return 0;  // unknown
  // The whole-image blocks this process keeps for reuse are its to use.
  return kib * 1024 + detail::keptBytes();
}

OutputSet::~OutputSet() {
  for (const Staged& s : staged_) std::remove(s.tmp.c_str());
}

void OutputSet::addExr(const std::string& path, const Film& film, const ExrOptions& options) {
  removeStaleTemporaries(path);
  Staged s{path, siblingPath(path, ".tmp")};
  writeExrFile(path, s.tmp, film, options);
  staged_.push_back(std::move(s));
}

void OutputSet::addPngRgb8(const std::string& path, int width, int height, const unsigned char* rgb) {
  removeStaleTemporaries(path);
  Staged s{path, siblingPath(path, ".tmp")};
  writePngFile(path, s.tmp, width, height, rgb);
  staged_.push_back(std::move(s));
}

void OutputSet::addText(const std::string& path, const std::string& bytes) {
  removeStaleTemporaries(path);
  Staged s{path, siblingPath(path, ".tmp")};
  writeBytesFile(path, s.tmp, bytes.data(), bytes.size());
  staged_.push_back(std::move(s));
}

void OutputSet::addFile(const std::string& path, const std::function<void(const std::string& tmp)>& write) {
  checkWritable(path);
  removeStaleTemporaries(path);
  Staged s{path, siblingPath(path, ".tmp")};
  try {
    write(s.tmp);
  } catch (...) {
    std::remove(s.tmp.c_str());
    throw;
  }
  staged_.push_back(std::move(s));
}

void OutputSet::addPreviewPng(const std::string& path, const Film& film) {
  const std::vector<unsigned char> px = previewPixels(film);
  addPngRgb8(path, film.width(), film.height(), px.data());
}

void OutputSet::commit() {
  const CommitHook hook = commitHook();
  if (hook.kill) ::kill(getpid(), SIGKILL);
  std::vector<std::string> dests;
  for (const Staged& s : staged_) dests.push_back(s.dest);
  const DirectoryLocks locks(dests);
  // Keep each destination's current file under a second name (a hard link:
  // no copy) so a later failed move can put it back.
  std::vector<std::string> backups(staged_.size());
  for (size_t i = 0; i < staged_.size(); ++i) {
    std::error_code ec;
    if (!fs::exists(staged_[i].dest, ec)) continue;
    backups[i] = siblingPath(staged_[i].dest, ".bak");
    fs::remove(backups[i], ec);
    fs::create_hard_link(staged_[i].dest, backups[i], ec);
    if (ec) backups[i].clear();  // no hard links here: the move itself is still atomic per file
  }
  auto dropBackups = [&] {
    for (const std::string& b : backups)
      if (!b.empty()) std::remove(b.c_str());
  };
  for (size_t i = 0; i < staged_.size(); ++i) {
    std::error_code ec;
    fs::rename(staged_[i].tmp, staged_[i].dest, ec);
    if (!ec) {
      if (i == 0 && hook.pause > 0) std::this_thread::sleep_for(std::chrono::duration<double>(hook.pause));
      continue;
    }
    // Undo the moves already made: restore the old file or remove the new one.
    for (size_t j = 0; j < i; ++j) {
      std::error_code ignored;
      if (!backups[j].empty())
        fs::rename(backups[j], staged_[j].dest, ignored);
      else
        fs::remove(staged_[j].dest, ignored);
    }
    dropBackups();
    throw Error(staged_[i].dest + ": cannot rename the temporary file into place: " + ec.message());
  }
  dropBackups();
  staged_.clear();
}

void writeExr(const std::string& path, const Film& film, const ExrOptions& options) {
  OutputSet out;
  out.addExr(path, film, options);
  out.commit();
}

void writeRgbExr(const std::string& path, int width, int height, const std::vector<float>& rgb,
                 const std::vector<HeaderAttribute>& attributes) {
  if (width < 1 || height < 1 || rgb.size() != size_t(width) * size_t(height) * 3)
    throw Error(path + ": write failed: " + std::to_string(rgb.size()) + " floats are not " + std::to_string(width) + "x" +
                std::to_string(height) + " RGB texels");
  OutputSet out;
  out.addFile(path, [&](const std::string& tmp) {
    const Imath::Box2i window({0, 0}, {width - 1, height - 1});
    Imf::Header header(window, window);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    insertHeaderAttributes(header, attributes);
    // One interleaved buffer: each channel's slice starts at its offset
    // and strides over the other two.
    Imf::FrameBuffer frame;
    const size_t xs = 3 * sizeof(float), ys = size_t(width) * xs;
    for (int c = 0; c < 3; ++c)
      frame.insert(std::string(1, "RGB"[c]),
                   Imf::Slice(Imf::FLOAT, (char*)(rgb.data() + c), xs, ys));
    writeExrChecked(path, tmp, header, [&](Imf::OutputFile& file) {
      file.setFrameBuffer(frame);
      file.writePixels(height);
    });
  });
  out.commit();
}

unsigned char linearToSrgb8(float v) {
  const float c = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
  return (unsigned char)std::lround(255.0f * linearToSrgb(c));
}

void writePreviewPng(const std::string& path, const Film& film) {
  OutputSet out;
  out.addPreviewPng(path, film);
  out.commit();
}

void writeTextFile(const std::string& path, const std::string& bytes) {
  OutputSet out;
  out.addText(path, bytes);
  out.commit();
}

void writePngRgb8(const std::string& path, int width, int height, const unsigned char* rgb) {
  OutputSet out;
  out.addPngRgb8(path, width, height, rgb);
  out.commit();
}

const char* exrCompressionName(ExrCompression c) { return kCompressionNames[int(c)]; }

ExrCompression exrCompressionFromName(const std::string& name, const std::string& what) {
  std::string lower = name, all;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
  for (const auto& [c, theirs] : kCompressions) {
    if (lower == kCompressionNames[int(c)]) return c;
    all += std::string(all.empty() ? "" : ", ") + kCompressionNames[int(c)];
  }
  throw Error(what + ": unknown compression '" + name + "' (one of " + all + ")");
}

bool isExrFile(const std::string& path) {
  checkInputFile(path);
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw Error(path + ": cannot open: " + std::strerror(errno));
  unsigned char magic[4] = {0, 0, 0, 0};
  const size_t n = std::fread(magic, 1, 4, f);
  std::fclose(f);
  return n == 4 && magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01;
}

std::string readExrAttribute(const std::string& path, const std::string& name) {
  if (!isExrFile(path)) return oiioModule(path).readStringAttribute(path, name);
  try {
    const Imf::InputFile in(path.c_str());
    const auto* s = in.header().findTypedAttribute<Imf::StringAttribute>(name);
    return s ? s->value() : std::string();
  } catch (const std::exception& e) {
    throw Error(path + ": cannot open: " + e.what());
  }
}

ExrImage readExrImage(const std::string& path) {
  if (!isExrFile(path)) throw Error(path + ": not an OpenEXR file");
  ExrImage img;
  try {
    Imf::InputFile in(path.c_str());
    const Imf::Header& h = in.header();
    const Imath::Box2i data = h.dataWindow();
    img.width = data.max.x - data.min.x + 1;
    img.height = data.max.y - data.min.y + 1;
    img.originX = data.min.x, img.originY = data.min.y;
    const size_t pixels = size_t(img.width) * size_t(img.height);
    Imf::FrameBuffer frame;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it) img.names.push_back(it.name());
    requireMemory(uint64_t(pixels) * img.names.size() * sizeof(float),
                  path + ": data window " + std::to_string(img.width) + "x" + std::to_string(img.height) + ", " +
                      std::to_string(img.names.size()) + " channels");
    img.planes.resize(img.names.size());
    for (size_t c = 0; c < img.names.size(); ++c) {
      img.planes[c].resize(pixels);
      frame.insert(img.names[c], Imf::Slice::Make(Imf::FLOAT, img.planes[c].data(), data, sizeof(float),
                                                  size_t(img.width) * sizeof(float)));
    }
    in.setFrameBuffer(frame);
    in.readPixels(data.min.y, data.max.y);
    for (auto it = h.begin(); it != h.end(); ++it) {
      const Imf::Attribute& a = it.attribute();
      if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&a)) img.attributes.push_back({it.name(), s->value()});
      else if (const auto* i = dynamic_cast<const Imf::IntAttribute*>(&a)) img.attributes.push_back({it.name(), i->value()});
      else if (const auto* f = dynamic_cast<const Imf::FloatAttribute*>(&a)) img.attributes.push_back({it.name(), f->value()});
      else if (const auto* m = dynamic_cast<const Imf::M44fAttribute*>(&a)) {
        std::vector<float> v;
        for (int r = 0; r < 4; ++r)
          for (int k = 0; k < 4; ++k) v.push_back(m->value()[r][k]);
        img.attributes.push_back({it.name(), v});
      }
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(path + ": cannot read: " + e.what());
  }
  return img;
}

}  // namespace obscura
