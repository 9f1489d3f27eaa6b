// Frames as a camera writes them into a directory: the files of a live stream, each reported once, and only
// when every byte of it is there (the input of `aosr watch`, solvers/quick_look.hpp).
//
// ## When is a file complete?
//
// A camera's writer either creates the file under a temporary name and renames it into place (then the file is
// whole when it appears), or writes it in place, possibly in several writes or even several open/close rounds.
// A reader must never read such a file half-way. Two checks, both needed:
//   * an event: Linux inotify's IN_CLOSE_WRITE (a writer closed the file) or IN_MOVED_TO (renamed into the
//     directory). Without inotify (or when its queue overflows) the directory is scanned every
//     poll_interval_s and a file is a candidate once its size and modification time held still for one scan;
//   * the content: FitsFileIsComplete below. A FITS file announces its own length: each HDU is a header of
//     2880-byte blocks ending with END, then |BITPIX|/8 · GCOUNT · (PCOUNT + NAXIS1 · … · NAXISn) bytes of data
//     padded to 2880 (FITS Standard 4.0, sections 3.3 and 4.4.1). A file shorter than its headers announce,
//     or whose last header has no END yet, is not complete: it stays pending, and a later event or scan looks
//     again.
// Two kinds of writer would pass both checks too early, and must write under a temporary name and rename (the
// usual practice, and what aosr's own writers do): one that preallocates the whole file and then fills it, and
// one that writes a file of several HDUs in place, closing it in between (cut after a whole HDU, a file is a
// valid FITS file of fewer HDUs).
//
// Names: files ending in one of `suffixes` (case-insensitive); names starting with '.' (editors' and rsync's
// temporaries) are ignored, as are aosr's own temporaries (".tmp-<pid>-<n>" after the suffix). A name written
// again after it was reported (a camera cycling through file names) is reported again when its modification
// time or size changed.
//
// Order: the order in which files became complete, which for a camera is the order it wrote them; with
// `existing` the files already present come first, in name order.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace aosr {

// True when the file at `path` is a FITS file holding every byte its headers announce (all HDUs, the last one's
// data padding included). false and the reason in *why otherwise (too short, no END yet, not FITS). IoError only
// when the file cannot be opened at all (e.g. removed).
bool FitsFileIsComplete(const std::string& path, std::string* why = nullptr);

struct DirectoryWatchOptions {
  // Report the matching files already in the directory when watching starts (in name order) before new ones.
  // false: only files that become complete afterwards (a quick-look started mid-night ignores older frames).
  bool existing = false;
  // Seconds between scans of the directory: the fallback without inotify, and a safety net with it (a missed or
  // overflowed event delays a file by at most this). > 0. 1 s: cheap (one readdir), and rare with inotify.
  double poll_interval_s = 1.0;
  // A pending file that stays incomplete, with no change of size, this long is given up (reported by
  // TakeAbandoned, never by Next). > 0. 60 s: longer than any sane writer's pause between writes.
  double abandon_after_s = 60.0;
  // Force the scanning fallback even where inotify works (tests of that path).
  bool disable_inotify = false;
  // File-name endings that are frames (case-insensitive). Non-empty.
  std::vector<std::string> suffixes = {".fits", ".fit", ".fts"};

  bool IsValid(std::string* why) const;
};

struct WatchedFile {
  std::string path;            // directory / name
  std::string name;            // file name
  std::uintmax_t bytes = 0;
  double mtime_unix_s = 0;     // the file's last modification (wall clock, s since 1970): when it was completed
  double complete_unix_s = 0;  // when the watcher found it complete (wall clock)
};

class DirectoryWatcher {
 public:
  // Starts watching `directory` (which must exist: IoError naming it otherwise; InvalidArgument for options).
  DirectoryWatcher(const std::string& directory, const DirectoryWatchOptions& options = {});
  ~DirectoryWatcher();
  DirectoryWatcher(const DirectoryWatcher&) = delete;
  DirectoryWatcher& operator=(const DirectoryWatcher&) = delete;

  // The next complete file, waiting up to timeout_s (>= 0; 0: only what is ready now). nullopt on timeout.
  std::optional<WatchedFile> Next(double timeout_s);
  // Whether a complete file is waiting now (no wait): a consumer that is behind can skip work that the next file
  // makes stale (the quick-look writes only the newest output).
  bool Ready();
  // Files given up as incomplete since the last call (path and the reason), each once.
  std::vector<std::pair<std::string, std::string>> TakeAbandoned();
  // Whether inotify is in use (false: scanning).
  bool using_inotify() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace aosr
