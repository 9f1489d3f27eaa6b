// Directory watching for live frames (include/aosr/io/frame_watch.hpp): inotify where the kernel has it, a scan
// of the directory otherwise, and the FITS length check that keeps half-written files out.
#include "aosr/io/frame_watch.hpp"

#include <poll.h>
#include <sys/inotify.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <thread>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

namespace fs = std::filesystem;
constexpr std::uintmax_t kBlock = 2880;  // FITS logical record
constexpr int kCard = 80;

double NowUnix() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string Lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// The integer value of a header card "KEYWORD = value / comment", or nullopt when it is not an integer.
std::optional<long long> CardInteger(const char* card) {
  std::string v(card + 10, card + kCard);
  const std::size_t slash = v.find('/');
  if (slash != std::string::npos) v.resize(slash);
  v.erase(0, v.find_first_not_of(' '));
  v.erase(v.find_last_not_of(' ') + 1);
  if (v.empty()) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const long long x = std::strtoll(v.c_str(), &end, 10);
  if (errno != 0 || end == v.c_str() || *end != '\0') return std::nullopt;
  return x;
}

bool CardIs(const char* card, const char* keyword) {
  const std::size_t n = std::strlen(keyword);
  if (std::memcmp(card, keyword, n) != 0) return false;
  for (std::size_t i = n; i < 8; ++i)
    if (card[i] != ' ') return false;
  return true;
}

bool SetWhy(std::string* why, const std::string& text) {
  if (why) *why = text;
  return false;
}

}  // namespace

bool FitsFileIsComplete(const std::string& path, std::string* why) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, "cannot open: " + std::string(std::strerror(errno)));
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) throw IoError(path, "cannot read its size: " + ec.message());
  if (size == 0) return SetWhy(why, "empty");
  std::uintmax_t at = 0;  // start of the current HDU
  std::array<char, kBlock> block{};
  for (int hdu = 0;; ++hdu) {
    if (hdu > 0) {
      // After the last HDU: the file ends, or the next one's header begins (possibly only partly written).
      if (at == size) return true;
      const std::uintmax_t left = std::min<std::uintmax_t>(size - at, 8);
      in.seekg(std::streamoff(at));
      char head[8] = {};
      in.read(head, std::streamsize(left));
      if (std::memcmp(head, "XTENSION", std::size_t(left)) != 0) return true;  // special records: not an HDU
    }
    // The header: blocks up to the one holding END.
    long long bitpix = 0, naxis = -1, pcount = 0, gcount = 1;
    std::vector<long long> axes;
    bool groups = false, ended = false;
    std::uintmax_t pos = at;
    while (!ended) {
      if (pos + kBlock > size)
        return SetWhy(why, "HDU " + std::to_string(hdu) + "'s header has no END within the " + std::to_string(size) +
                               " bytes written so far");
      in.seekg(std::streamoff(pos));
      in.read(block.data(), std::streamsize(kBlock));
      if (!in) throw IoError(path, "read failed at byte " + std::to_string(pos));
      if (pos == at && hdu == 0 && std::memcmp(block.data(), "SIMPLE  ", 8) != 0)
        return SetWhy(why, "not a FITS file (no SIMPLE card)");
      for (int c = 0; c < int(kBlock) / kCard; ++c) {
        const char* card = block.data() + c * kCard;
        if (CardIs(card, "END")) {
          ended = true;
          break;
        }
        if (card[8] != '=') continue;
        if (CardIs(card, "BITPIX")) {
          bitpix = CardInteger(card).value_or(0);
        } else if (CardIs(card, "NAXIS")) {
          naxis = CardInteger(card).value_or(-1);
        } else if (std::memcmp(card, "NAXIS", 5) == 0 && card[5] >= '1' && card[5] <= '9') {
          const int k = std::atoi(std::string(card + 5, card + 8).c_str());
          if (k >= 1 && k <= 999) {
            if (int(axes.size()) < k) axes.resize(std::size_t(k), -1);
            axes[std::size_t(k - 1)] = CardInteger(card).value_or(-1);
          }
        } else if (CardIs(card, "PCOUNT")) {
          pcount = CardInteger(card).value_or(-1);
        } else if (CardIs(card, "GCOUNT")) {
          gcount = CardInteger(card).value_or(-1);
        } else if (CardIs(card, "GROUPS")) {
          groups = std::string(card + 10, card + 30).find('T') != std::string::npos;
        }
      }
      pos += kBlock;
    }
    const std::string where = "HDU " + std::to_string(hdu);
    if (bitpix == 0 || std::abs(bitpix) % 8 != 0 || naxis < 0 || naxis > 999 || pcount < 0 || gcount < 0)
      return SetWhy(why, where + ": malformed BITPIX/NAXIS/PCOUNT/GCOUNT");
    if (int(axes.size()) < naxis) return SetWhy(why, where + ": missing NAXISn");
    // Data bytes (FITS 4.0 eq. 1 and 2; random groups skip NAXIS1 = 0).
    std::uintmax_t data = 0;
    if (naxis > 0) {
      std::uintmax_t product = 1;
      for (long long k = (hdu == 0 && groups) ? 1 : 0; k < naxis; ++k) {
        if (axes[std::size_t(k)] < 0) return SetWhy(why, where + ": negative NAXIS" + std::to_string(k + 1));
        product *= std::uintmax_t(axes[std::size_t(k)]);
      }
      data = std::uintmax_t(std::abs(bitpix) / 8) * std::uintmax_t(gcount) * (std::uintmax_t(pcount) + product);
    }
    const std::uintmax_t padded = (data + kBlock - 1) / kBlock * kBlock;
    if (pos + padded > size)
      return SetWhy(why, where + " announces " + std::to_string(pos + padded) + " bytes; " + std::to_string(size) +
                             " written so far");
    at = pos + padded;
  }
}

bool DirectoryWatchOptions::IsValid(std::string* why) const {
  auto bad = [why](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  if (!(std::isfinite(poll_interval_s) && poll_interval_s > 0)) return bad("poll_interval_s must be finite and > 0");
  if (!(std::isfinite(abandon_after_s) && abandon_after_s > 0)) return bad("abandon_after_s must be finite and > 0");
  if (suffixes.empty()) return bad("suffixes must not be empty");
  for (const std::string& s : suffixes)
    if (s.empty()) return bad("suffixes must not hold an empty ending");
  return true;
}

struct DirectoryWatcher::Impl {
  struct Stamp {
    std::uintmax_t bytes = 0;
    long long mtime_ns = 0;
    bool operator==(const Stamp& o) const { return bytes == o.bytes && mtime_ns == o.mtime_ns; }
  };
  struct Pending {
    Stamp stamp;
    double changed_s = 0;  // when its stamp last changed (steady clock)
    bool stamp_seen_before = false;
    std::string why;
  };

  std::string dir;
  DirectoryWatchOptions options;
  int fd = -1;
  std::map<std::string, Stamp> reported;  // name -> stamp when reported (or abandoned, or present at start)
  std::map<std::string, Pending> pending;
  std::deque<WatchedFile> ready;
  std::vector<std::pair<std::string, std::string>> abandoned;
  double next_scan_s = 0;

  static double Steady() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  }

  bool Matches(const std::string& name) const {
    if (name.empty() || name[0] == '.') return false;
    const std::string low = Lower(name);
    for (const std::string& s : options.suffixes) {
      const std::string ls = Lower(s);
      if (low.size() > ls.size() && low.compare(low.size() - ls.size(), ls.size(), ls) == 0) return true;
    }
    return false;
  }

  bool StampOf(const std::string& name, Stamp* s) const {
    struct stat st {};
    if (::stat((dir + "/" + name).c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
    s->bytes = std::uintmax_t(st.st_size);
    s->mtime_ns = (long long)st.st_mtim.tv_sec * 1000000000LL + st.st_mtim.tv_nsec;
    return true;
  }

  // Looks at `name` now: ready if complete, pending otherwise. `settled`: an event says a writer closed it (or
  // it was renamed in), or it held still since the last scan.
  void Consider(const std::string& name, bool settled) {
    Stamp s;
    if (!StampOf(name, &s)) {
      pending.erase(name);
      return;
    }
    auto r = reported.find(name);
    if (r != reported.end() && r->second == s) return;  // nothing new
    const double now = Steady();
    Pending& p = pending[name];
    const bool changed = !(p.stamp == s) || !p.stamp_seen_before;
    if (changed) {
      p.stamp = s;
      p.changed_s = now;
    }
    const bool still = p.stamp_seen_before && !changed;
    p.stamp_seen_before = true;
    if (!settled && !still) return;
    std::string why;
    bool complete = false;
    try {
      complete = FitsFileIsComplete(dir + "/" + name, &why);
    } catch (const IoError&) {
      pending.erase(name);  // removed between the stat and the open
      return;
    }
    // The check reads the file after the stat: a writer that appended in between leaves a whole file behind a
    // stale stamp, and the later stamp would report it again. Report only a file whose stamp held through the
    // check; otherwise it changed, and the next event or scan looks again.
    Stamp after;
    if (complete && !StampOf(name, &after)) {
      pending.erase(name);
      return;
    }
    if (complete && !(after == s)) {
      p.stamp = after;
      p.changed_s = now;
      return;
    }
    if (complete) {
      WatchedFile f;
      f.path = dir + "/" + name;
      f.name = name;
      f.bytes = s.bytes;
      f.mtime_unix_s = double(s.mtime_ns) * 1e-9;
      f.complete_unix_s = NowUnix();
      ready.push_back(std::move(f));
      reported[name] = s;
      pending.erase(name);
      return;
    }
    p.why = why;
    if (now - p.changed_s >= options.abandon_after_s) {
      abandoned.emplace_back(dir + "/" + name, why);
      reported[name] = s;
      pending.erase(name);
    }
  }

  std::vector<std::string> List() const {
    std::vector<std::string> names;
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (Matches(name)) names.push_back(name);
    }
    std::sort(names.begin(), names.end());
    return names;
  }

  void Scan() {
    for (const std::string& name : List()) Consider(name, false);
    // Pending files that vanished, or that stayed incomplete too long.
    std::vector<std::string> names;
    for (const auto& [name, p] : pending) names.push_back(name);
    for (const std::string& name : names) {
      Stamp s;
      if (!StampOf(name, &s)) pending.erase(name);
    }
    const double now = Steady();
    for (auto it = pending.begin(); it != pending.end();) {
      if (now - it->second.changed_s >= options.abandon_after_s) {
        abandoned.emplace_back(dir + "/" + it->first, it->second.why.empty() ? "never complete" : it->second.why);
        reported[it->first] = it->second.stamp;
        it = pending.erase(it);
      } else {
        ++it;
      }
    }
    next_scan_s = Steady() + options.poll_interval_s;
  }

  // Reads every queued inotify event; returns false when the queue overflowed (then a scan must run).
  bool Drain() {
    alignas(struct inotify_event) char buf[16384];
    bool ok = true;
    for (;;) {
      const ssize_t n = ::read(fd, buf, sizeof buf);
      if (n <= 0) break;
      for (char* p = buf; p < buf + n;) {
        const auto* e = reinterpret_cast<const struct inotify_event*>(p);
        if (e->mask & IN_Q_OVERFLOW) ok = false;
        if (e->len > 0) {
          const std::string name(e->name);
          if (Matches(name) && (e->mask & (IN_CLOSE_WRITE | IN_MOVED_TO))) Consider(name, true);
        }
        p += sizeof(struct inotify_event) + e->len;
      }
    }
    return ok;
  }
};

DirectoryWatcher::DirectoryWatcher(const std::string& directory, const DirectoryWatchOptions& options)
    : impl_(std::make_unique<Impl>()) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("DirectoryWatcher: options." + why);
  std::error_code ec;
  if (!fs::is_directory(directory, ec)) throw IoError(directory, "is not a directory (aosr watches an existing one)");
  impl_->dir = directory;
  impl_->options = options;
  if (!options.disable_inotify) {
    impl_->fd = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (impl_->fd >= 0 && ::inotify_add_watch(impl_->fd, directory.c_str(), IN_CLOSE_WRITE | IN_MOVED_TO) < 0) {
      ::close(impl_->fd);
      impl_->fd = -1;
    }
  }
  // Watching starts before the first listing, so that nothing written in between is missed.
  for (const std::string& name : impl_->List()) {
    if (options.existing) {
      impl_->Consider(name, true);
    } else {
      Impl::Stamp s;
      if (impl_->StampOf(name, &s)) impl_->reported[name] = s;
    }
  }
  impl_->next_scan_s = Impl::Steady() + options.poll_interval_s;
}

DirectoryWatcher::~DirectoryWatcher() {
  if (impl_ && impl_->fd >= 0) ::close(impl_->fd);
}

bool DirectoryWatcher::using_inotify() const { return impl_->fd >= 0; }

std::optional<WatchedFile> DirectoryWatcher::Next(double timeout_s) {
  CheckArgument(std::isfinite(timeout_s) && timeout_s >= 0, "DirectoryWatcher::Next", "timeout_s", timeout_s,
                "finite and >= 0");
  Impl& m = *impl_;
  const double deadline = Impl::Steady() + timeout_s;
  for (;;) {
    if (m.fd >= 0 && !m.Drain()) m.Scan();
    if (Impl::Steady() >= m.next_scan_s) m.Scan();
    if (!m.ready.empty()) {
      WatchedFile f = std::move(m.ready.front());
      m.ready.pop_front();
      return f;
    }
    const double now = Impl::Steady();
    if (now >= deadline) return std::nullopt;
    const double wait = std::max(0.0, std::min(deadline, m.next_scan_s) - now);
    if (m.fd >= 0) {
      struct pollfd p {};
      p.fd = m.fd;
      p.events = POLLIN;
      ::poll(&p, 1, int(std::ceil(wait * 1e3)));
    } else {
      std::this_thread::sleep_for(std::chrono::duration<double>(std::min(wait, 0.01)));
    }
  }
}

bool DirectoryWatcher::Ready() {
  Impl& m = *impl_;
  if (m.fd >= 0 && !m.Drain()) m.Scan();
  if (Impl::Steady() >= m.next_scan_s) m.Scan();
  return !m.ready.empty();
}

std::vector<std::pair<std::string, std::string>> DirectoryWatcher::TakeAbandoned() {
  std::vector<std::pair<std::string, std::string>> out;
  out.swap(impl_->abandoned);
  return out;
}

}  // namespace aosr
