#include "core/render/checkpoint.h"
#include "core/util/input_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <obscura/error.h>

namespace obscura {
namespace {

constexpr char kMagic[8] = {'O', 'B', 'S', 'C', 'K', 'P', 'T', '\0'};
constexpr uint32_t kByteOrder = 0x01020304;

uint64_t fnv1a(const unsigned char* p, size_t n) {
  uint64_t h = 1469598103934665603ull;
  for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

// Appends plain values to a byte buffer.
struct Writer {
  std::vector<unsigned char>& out;
  template <class T>
  void put(const T& v) {
    const auto* p = reinterpret_cast<const unsigned char*>(&v);
    out.insert(out.end(), p, p + sizeof v);
  }
  void str(const std::string& s) {
    put(uint32_t(s.size()));
    out.insert(out.end(), s.begin(), s.end());
  }
};

// Reads them back, every read bounds-checked: a short file is "truncated",
// never a read past the end.
struct Reader {
  const std::vector<unsigned char>& in;
  size_t end;  // the hash's offset
  const std::string& path;
  size_t at = 0;
  void need(size_t n) const {
    if (n > end - at) throw Error(path + ": truncated checkpoint (delete it to start over)");
  }
  template <class T>
  T get() {
    need(sizeof(T));
    T v;
    std::memcpy(&v, in.data() + at, sizeof v);
    at += sizeof v;
    return v;
  }
  std::string str() {
    const uint32_t n = get<uint32_t>();
    need(n);
    std::string s(reinterpret_cast<const char*>(in.data() + at), n);
    at += n;
    return s;
  }
};

std::string errnoText() { return std::strerror(errno); }

}  // namespace

Checkpoint::Checkpoint(std::string path, double intervalSeconds) : path_(std::move(path)), interval_(intervalSeconds) {
  if (const char* k = std::getenv("OBSCURA_TEST_CHECKPOINT_KILL"); k && *k) {
    char* end = nullptr;
    killAfter_ = size_t(std::strtoull(k, &end, 10));
    killSignal_ = (end && std::strcmp(end, ":INT") == 0) ? SIGINT : SIGKILL;
  }
}

Checkpoint::~Checkpoint() = default;

void Checkpoint::checkPath() const {
  // A directory at the path failed inside libstdc++ ("basic_filebuf::underflow
  // error reading the file: Is a directory"), naming neither the file nor the
  // option; a FIFO blocked the read forever.
  checkInputFile(path_, "--checkpoint ");
}

bool Checkpoint::read() {
  std::error_code ec;
  if (!std::filesystem::exists(path_, ec)) return false;
  checkPath();
  {
    std::ifstream in(path_, std::ios::binary);
    if (!in) throw Error(path_ + ": cannot read the checkpoint");
    bytes_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (in.bad()) throw Error(path_ + ": cannot read the checkpoint");
  }
  const std::string again = " (delete it to start over)";
  if (bytes_.size() < sizeof kMagic || std::memcmp(bytes_.data(), kMagic, sizeof kMagic) != 0)
    throw Error(path_ + ": not an Obscura checkpoint" + again);
  if (bytes_.size() < sizeof kMagic + 2 * sizeof(uint32_t) + sizeof(uint64_t))
    throw Error(path_ + ": truncated checkpoint" + again);
  Reader r{bytes_, bytes_.size() - sizeof(uint64_t), path_};
  r.at = sizeof kMagic;
  if (const uint32_t v = r.get<uint32_t>(); v != kFormatVersion)
    throw Error(path_ + ": checkpoint format version " + std::to_string(v) + ", this obscura reads version " +
                std::to_string(kFormatVersion) + again);
  if (r.get<uint32_t>() != kByteOrder) throw Error(path_ + ": checkpoint written on a machine of another byte order" + again);
  uint64_t hash;
  std::memcpy(&hash, bytes_.data() + r.end, sizeof hash);
  if (hash != fnv1a(bytes_.data(), r.end)) throw Error(path_ + ": corrupt checkpoint (its checksum does not match)" + again);

  const uint32_t keys = r.get<uint32_t>();
  for (uint32_t i = 0; i < keys; ++i) {
    std::string k = r.str();
    savedFingerprint_.emplace_back(std::move(k), r.str());
  }
  savedWindow_.x0 = r.get<int32_t>(), savedWindow_.y0 = r.get<int32_t>();
  savedWindow_.x1 = r.get<int32_t>(), savedWindow_.y1 = r.get<int32_t>();
  savedTileSize_ = r.get<int32_t>();
  savedTileCount_ = r.get<int32_t>();
  if (savedWindow_.width() <= 0 || savedWindow_.height() <= 0 || savedTileSize_ <= 0 ||
      savedTileCount_ != PixelRect::tileCount(savedTileSize_, savedWindow_.width(), savedWindow_.height()))
    throw Error(path_ + ": corrupt checkpoint (window and tiles disagree)" + again);
  const uint32_t channels = r.get<uint32_t>();
  r.need(size_t(channels) * sizeof(uint32_t));
  for (uint32_t c = 0; c < channels; ++c) savedChannels_.push_back(r.str());
  earlierSeconds_ = r.get<double>();
  earlierRuns_ = r.get<uint32_t>();
  const uint32_t tiles = r.get<uint32_t>();
  if (tiles > uint32_t(savedTileCount_)) throw Error(path_ + ": corrupt checkpoint (more tiles than the window has)" + again);
  std::vector<bool> seen(size_t(savedTileCount_), false);
  for (uint32_t i = 0; i < tiles; ++i) {
    LoadedTile t;
    t.index = int(r.get<uint32_t>());
    if (t.index < 0 || t.index >= savedTileCount_ || seen[size_t(t.index)])
      throw Error(path_ + ": corrupt checkpoint (tile index " + std::to_string(t.index) + ")" + again);
    seen[size_t(t.index)] = true;
    t.rays.camera = r.get<uint64_t>();
    t.rays.occlusion = r.get<uint64_t>();
    t.rays.closest = r.get<uint64_t>();
    const PixelRect rect = PixelRect::tile(t.index, savedTileSize_, savedWindow_.width(), savedWindow_.height());
    const size_t n = rect.size() * channels * sizeof(float);
    r.need(n);
    t.offset = r.at;
    r.at += n;
    loadedTiles_.push_back(t);
  }
  if (r.at != r.end) throw Error(path_ + ": corrupt checkpoint (trailing bytes)" + again);
  savedTiles_ = loadedTiles_.size();
  loaded_ = true;
  return true;
}

void Checkpoint::setFingerprint(Fingerprint fp) {
  fingerprint_ = std::move(fp);
  if (!loaded_) return;
  const std::string how = "; delete it to start over, or run the render that wrote it";
  const auto find = [](const Fingerprint& f, const std::string& key) -> const std::string* {
    for (const auto& [k, v] : f)
      if (k == key) return &v;
    return nullptr;
  };
  // Values can be long (matrices, Cryptomatte manifests): the line stays short.
  const auto quoted = [](const std::string* v) {
    if (!v) return std::string("(none)");
    return "'" + (v->size() > 60 ? v->substr(0, 57) + "..." : *v) + "'";
  };
  const auto refuse = [&](const std::string& key, const std::string* then, const std::string* now) {
    throw Error(path_ + ": checkpoint of a different render (" + key + ": " + quoted(then) + " in the checkpoint, " +
                quoted(now) + " now)" + how);
  };
  // The first key, in the checkpoint's order, whose value differs or is gone;
  // then the first key this render has and the checkpoint lacks.
  for (const auto& [k, v] : savedFingerprint_)
    if (const std::string* now = find(fingerprint_, k); !now || *now != v) refuse(k, &v, now);
  for (const auto& [k, v] : fingerprint_)
    if (!find(savedFingerprint_, k)) refuse(k, nullptr, &v);
}

PixelRect Checkpoint::tileRect(int t) const {
  const PixelRect w = film_->window();
  PixelRect r = PixelRect::tile(t, tileSize_, w.width(), w.height());
  r.x0 += w.x0, r.x1 += w.x0, r.y0 += w.y0, r.y1 += w.y0;
  return r;
}

void Checkpoint::start(Film& film, int tileSize, int tileCount) {
  film_ = &film;
  tileSize_ = tileSize;
  tileCount_ = tileCount;
  done_ = std::make_unique<std::atomic<uint8_t>[]>(size_t(tileCount));
  for (int t = 0; t < tileCount; ++t) done_[size_t(t)].store(0, std::memory_order_relaxed);
  tileRays_.assign(size_t(tileCount), RayCounters{});
  t0_ = std::chrono::steady_clock::now();
  lastWrite_.store(t0_.time_since_epoch().count(), std::memory_order_relaxed);
  if (!loaded_) return;
  // The fingerprint makes these equal; checked again so that a file that
  // passed it by accident can never write outside the film.
  const std::string again = " (delete it to start over)";
  const PixelRect w = film.window();
  if (savedWindow_.x0 != w.x0 || savedWindow_.y0 != w.y0 || savedWindow_.x1 != w.x1 || savedWindow_.y1 != w.y1 ||
      savedTileSize_ != tileSize || savedTileCount_ != tileCount)
    throw Error(path_ + ": the checkpoint's window or tiles differ from this render's" + again);
  const std::vector<int>& channels = film.channels();
  bool same = channels.size() == savedChannels_.size();
  for (size_t c = 0; same && c < channels.size(); ++c) same = film.name(channels[c]) == savedChannels_[c];
  if (!same) throw Error(path_ + ": the checkpoint's channels differ from this render's" + again);
  for (const LoadedTile& t : loadedTiles_) {
    const PixelRect r = tileRect(t.index);
    const unsigned char* p = bytes_.data() + t.offset;
    for (int c : channels)
      for (int y = r.y0; y < r.y1; ++y) {
        std::memcpy(&film.at(c, r.x0, y), p, size_t(r.width()) * sizeof(float));
        p += size_t(r.width()) * sizeof(float);
      }
    tileRays_[size_t(t.index)] = t.rays;
    done_[size_t(t.index)].store(1, std::memory_order_relaxed);
  }
  std::vector<unsigned char>().swap(bytes_);  // in the film now
}

void Checkpoint::finished(int t, const RayCounters& rays) {
  tileRays_[size_t(t)] = rays;
  done_[size_t(t)].store(1, std::memory_order_release);
  const int64_t now = std::chrono::steady_clock::now().time_since_epoch().count();
  const double since = std::chrono::duration<double>(std::chrono::steady_clock::duration(now - lastWrite_.load())).count();
  if (since < interval_) return;
  if (writing_.exchange(true, std::memory_order_acquire)) return;  // another thread is writing
  try {
    write();
  } catch (const Error& e) {
    // The render goes on: the checkpoint is an aid, the image is the job.
    Log::warnOnce(e.what());
  }
  lastWrite_.store(std::chrono::steady_clock::now().time_since_epoch().count());
  writing_.store(false, std::memory_order_release);
}

void Checkpoint::save() { write(); }

RayCounters Checkpoint::rays() const {
  RayCounters sum;
  for (int t = 0; t < tileCount_; ++t)
    if (done(t)) {
      sum.camera += tileRays_[size_t(t)].camera;
      sum.occlusion += tileRays_[size_t(t)].occlusion;
      sum.closest += tileRays_[size_t(t)].closest;
    }
  return sum;
}

void Checkpoint::write() {
  // The tiles done now (acquire: their pixels and rays are visible); one
  // that finishes while this runs goes into the next checkpoint.
  std::vector<int> tiles;
  for (int t = 0; t < tileCount_; ++t)
    if (done(t)) tiles.push_back(t);

  // Temporary, flushed to the disk, renamed: after a crash or power loss the
  // file is the previous checkpoint or this one. Streamed in pieces of a few
  // MiB, hashed as it goes, so a write needs no second copy of the film.
  const std::string tmp = path_ + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(path_ + ": cannot write the checkpoint: " + errnoText());
  const auto fail = [&](const std::string& why) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw Error(path_ + ": cannot write the checkpoint: " + why);
  };
  std::vector<unsigned char> buf;
  const auto writeAll = [&] {
    size_t done = 0;
    while (done < buf.size()) {
      const ssize_t n = ::write(fd, buf.data() + done, buf.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) fail(errnoText());
      done += size_t(n);
    }
    buf.clear();
  };
  uint64_t hash = 1469598103934665603ull;  // FNV-1a 64 (fnv1a above), over every piece
  const auto flush = [&] {
    for (unsigned char c : buf) hash = (hash ^ c) * 1099511628211ull;
    writeAll();
  };
  Writer w{buf};
  buf.insert(buf.end(), kMagic, kMagic + sizeof kMagic);
  w.put(kFormatVersion);
  w.put(kByteOrder);
  w.put(uint32_t(fingerprint_.size()));
  for (const auto& [k, v] : fingerprint_) w.str(k), w.str(v);
  const PixelRect win = film_->window();
  for (int v : {win.x0, win.y0, win.x1, win.y1, tileSize_, tileCount_}) w.put(int32_t(v));
  const std::vector<int>& channels = film_->channels();
  w.put(uint32_t(channels.size()));
  for (int c : channels) w.str(film_->name(c));
  w.put(earlierSeconds_ + std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count());
  w.put(earlierRuns_ + 1);
  w.put(uint32_t(tiles.size()));
  for (int t : tiles) {
    w.put(uint32_t(t));
    w.put(tileRays_[size_t(t)].camera);
    w.put(tileRays_[size_t(t)].occlusion);
    w.put(tileRays_[size_t(t)].closest);
    const PixelRect r = tileRect(t);
    for (int c : channels)
      for (int y = r.y0; y < r.y1; ++y) {
        const auto* p = reinterpret_cast<const unsigned char*>(&film_->at(c, r.x0, y));
        buf.insert(buf.end(), p, p + size_t(r.width()) * sizeof(float));
      }
    if (buf.size() >= (size_t(4) << 20)) flush();
  }
  flush();
  w.put(hash);  // of everything before it
  writeAll();
  if (::fsync(fd) != 0) fail(errnoText());
  if (::close(fd) != 0) {
    const std::string why = errnoText();
    ::unlink(tmp.c_str());
    throw Error(path_ + ": cannot write the checkpoint: " + why);
  }
  if (::rename(tmp.c_str(), path_.c_str()) != 0) {
    const std::string why = errnoText();
    ::unlink(tmp.c_str());
    throw Error(path_ + ": cannot write the checkpoint: " + why);
  }
  savedTiles_ = tiles.size();
  if (killAfter_ > 0 && tiles.size() >= killAfter_ && !killed_.exchange(true)) ::raise(killSignal_);
}

void Checkpoint::remove() {
  std::error_code ec;
  std::filesystem::remove(path_, ec);
  std::filesystem::remove(path_ + ".tmp", ec);
}

}  // namespace obscura
