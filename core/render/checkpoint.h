// Resumable renders (docs/production.md "Checkpoints"): the finished tiles of a
// ray-traced render saved to a file between tiles, and skipped when the same
// render runs again.
//
// What is saved of a tile is its pixels as the film holds them once the tile
// is done. Every camera sample belongs to its own pixel (the pixel filter is
// importance-sampled: core/render/gbuffer.h cameraSampleFilm, no splatting into
// neighbours) and every pixel to exactly one tile, whose resolve writes the
// pixel's final value from the tile's own sums (core/render/render.cpp
// TileRenderer::resolve); nothing is added to a pixel after its tile ends.
// So a finished tile's float planes - R,G,B,A, the AOVs, every --pass layer,
// the Cryptomatte ranks - are final, and copying them back bit for bit
// resumes the render exactly where an uninterrupted one would be, for any
// thread count and whichever tiles happened to finish first.
//
// File (native byte order, checked): magic "OBSCKPT\0", u32 format version,
// u32 0x01020304, the fingerprint (u32 count, then u32-length-prefixed key
// and value strings), the window (4 x i32), tile size, tile count, the
// channel names, f64 seconds of earlier runs, u32 runs, u32 tiles saved, then
// per tile: u32 index, 3 x u64 rays (camera, occlusion, closest), the tile's
// pixels channel by channel (f32, row-major); last a u64 FNV-1a hash of
// everything before it. Written to PATH.tmp, flushed to disk, renamed over
// PATH: a reader sees the old file or the new one, never half of one.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/image/film.h"
#include <obscura/integrator.h>

namespace obscura {

// Everything that determines the image, as (key, value) pairs in a fixed
// order; the caller builds it (app/main.cpp: the EXR header's settings, the
// scene's bytes, the tile size, the version).
using Fingerprint = std::vector<std::pair<std::string, std::string>>;

class Checkpoint {
 public:
  static constexpr uint32_t kFormatVersion = 1;

  // `path` is the file; a write happens at most every `intervalSeconds`
  // (0: after every tile; each write rewrites every finished tile, so on a
  // large image that costs time).
  //
  // Tests only: OBSCURA_TEST_CHECKPOINT_KILL=N[:INT] makes the process send
  // itself SIGKILL (or SIGINT) right after it has written a checkpoint
  // holding at least N tiles - a deterministic interruption with interval 0
  // and one thread (with more, a thread that finishes a tile during another
  // thread's write does not write).
  Checkpoint(std::string path, double intervalSeconds);
  ~Checkpoint();
  Checkpoint(const Checkpoint&) = delete;
  Checkpoint& operator=(const Checkpoint&) = delete;

  const std::string& path() const { return path_; }

  // Reads the file if there is one; true if there was. Throws obscura::Error
  // naming the file and what is wrong (not a checkpoint, another format
  // version, truncated, corrupt).
  bool read();
  // Throws obscura::Error when something other than a regular file is at
  // the path (a directory): checked before the render starts.
  void checkPath() const;
  bool loaded() const { return loaded_; }
  // The fingerprint of this render. With a file read, throws obscura::Error
  // naming the first key whose value differs (and how to start over).
  void setFingerprint(Fingerprint fp);

  // --- the render loop (core/render/render.cpp) ------------------------------------
  // Before the tiles: the film (all its planes added), the tile size and
  // count of the window. Copies the saved tiles into the film (throws if the
  // file's window, tiles or channels do not fit it).
  void start(Film& film, int tileSize, int tileCount);
  // Whether tile t is done (saved, or finished in this run).
  bool done(int t) const { return done_[size_t(t)].load(std::memory_order_acquire) != 0; }
  // Called by the thread that finished tile t, after its pixels are in the
  // film, with the rays it traced. May write the file (one thread at a time;
  // the others go on rendering).
  void finished(int t, const RayCounters& rays);
  // Writes the file now (the render loop is over: the last save of an
  // interrupted render).
  void save();
  // After the loop: the rays of every done tile (so a resumed render counts
  // exactly the rays of an uninterrupted one) and the render-loop seconds of
  // the earlier runs.
  RayCounters rays() const;
  double earlierSeconds() const { return earlierSeconds_; }
  // Runs that rendered this image (1 when not resumed).
  int runs() const { return int(earlierRuns_) + 1; }
  size_t savedTiles() const { return savedTiles_; }  // in the file, as read or last written
  size_t loadedTiles() const { return loadedTiles_.size(); }
  int tileCount() const { return tileCount_; }

  // After the final image is written: deletes the file (and a stale PATH.tmp).
  void remove();

 private:
  void write();
  PixelRect tileRect(int t) const;

  std::string path_;
  double interval_;
  Fingerprint fingerprint_;
  // As read from the file.
  bool loaded_ = false;
  Fingerprint savedFingerprint_;
  PixelRect savedWindow_;
  int savedTileSize_ = 0, savedTileCount_ = 0;
  std::vector<std::string> savedChannels_;
  double earlierSeconds_ = 0;
  uint32_t earlierRuns_ = 0;
  std::vector<unsigned char> bytes_;
  struct LoadedTile {
    int index;
    RayCounters rays;
    size_t offset;  // of its pixels in bytes_
  };
  std::vector<LoadedTile> loadedTiles_;
  size_t savedTiles_ = 0;
  // The render in progress.
  Film* film_ = nullptr;
  int tileSize_ = 0, tileCount_ = 0;
  std::unique_ptr<std::atomic<uint8_t>[]> done_;
  std::vector<RayCounters> tileRays_;  // written by the tile's thread before done_ is set
  std::chrono::steady_clock::time_point t0_;
  std::atomic<int64_t> lastWrite_{0};  // steady_clock ticks
  std::atomic<bool> writing_{false};
  // OBSCURA_TEST_CHECKPOINT_KILL.
  size_t killAfter_ = 0;
  int killSignal_ = 0;
  std::atomic<bool> killed_{false};
};

}  // namespace obscura
