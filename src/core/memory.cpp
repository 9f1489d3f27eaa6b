#include "aosr/core/memory.hpp"

#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

std::atomic<double> g_override{0.0};

// Address space the process maps now (first field of /proc/self/statm, in pages); 0 if unknown.
double MappedBytes() {
  std::ifstream statm("/proc/self/statm");
  double pages = 0;
  if (!(statm >> pages)) return 0.0;
  return pages * double(sysconf(_SC_PAGESIZE));
}

}  // namespace

double ParseByteSize(const std::string& text, const std::string& what) {
  const auto bad = [&] {
    return InvalidArgument(what + ": \"" + text + "\" is not a memory size; allowed: a positive number of bytes, "
                           "optionally with a K, M, G or T suffix (powers of 1024), e.g. 8G");
  };
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    throw bad();
  }
  std::string rest = text.substr(used);
  if (!rest.empty() && (rest.back() == 'B' || rest.back() == 'b')) rest.pop_back();
  if (!rest.empty() && (rest.back() == 'i')) rest.pop_back();  // "GiB" reads as "G"
  double scale = 1;
  if (rest.size() == 1) {
    switch (std::toupper(static_cast<unsigned char>(rest[0]))) {
      case 'K': scale = 1024.0; break;
      case 'M': scale = 1024.0 * 1024; break;
      case 'G': scale = 1024.0 * 1024 * 1024; break;
      case 'T': scale = 1024.0 * 1024 * 1024 * 1024; break;
      default: throw bad();
    }
  } else if (!rest.empty()) {
    throw bad();
  }
  if (!std::isfinite(value) || value <= 0) throw bad();
  return value * scale;
}

std::string FormatBytes(double bytes) {
  static const char* kUnits[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  if (!std::isfinite(bytes)) return "an unbounded amount";
  int u = 0;
  while (bytes >= 1024.0 && u < 6) bytes /= 1024.0, ++u;
  char buf[64];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.3g %s", bytes, kUnits[u]);
  return buf;
}

void SetMemoryLimitBytes(double bytes) {
  if (!(bytes >= 0) || !std::isfinite(bytes))
    throw InvalidArgument("SetMemoryLimitBytes", "bytes", ToString(bytes), "a finite value >= 0 (0: the default)");
  g_override.store(bytes);
}

MemoryLimit CurrentMemoryLimit() {
  if (const double o = g_override.load(); o > 0) return {o, "set for this run"};
  if (const char* env = std::getenv("AOSR_MEMORY_LIMIT"); env != nullptr && *env != '\0')
    return {ParseByteSize(env, "AOSR_MEMORY_LIMIT"), std::string("AOSR_MEMORY_LIMIT=") + env};
  MemoryLimit limit{double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGESIZE)), "physical memory"};
  // Under `ulimit -v` (RLIMIT_AS) or a data limit the process gets what the limit leaves beyond what it maps
  // already; allocations past that fail even with free physical memory.
  for (const auto& [resource, name] : {std::pair{RLIMIT_AS, "ulimit -v"}, std::pair{RLIMIT_DATA, "ulimit -d"}}) {
    rlimit rl{};
    if (getrlimit(resource, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY) {
      const double left = std::max(0.0, double(rl.rlim_cur) - MappedBytes());
      if (left < limit.bytes) limit = {left, std::string("what ") + name + " leaves this process"};
    }
  }
  if (!(limit.bytes > 0)) limit = {0.0, "physical memory unknown"};
  return limit;
}

void CheckMemory(double bytes, const std::string& what) {
  const MemoryLimit limit = CurrentMemoryLimit();
  if (std::isfinite(bytes) && bytes >= 0 && (limit.bytes <= 0 || bytes <= limit.bytes)) return;
  throw ResourceError(what + " needs about " + FormatBytes(bytes) + " of memory (estimate), more than the limit of " +
                      FormatBytes(limit.bytes) + " (" + limit.source +
                      "); make the request smaller, or raise the limit with AOSR_MEMORY_LIMIT (e.g. 64G)");
}

double PeakResidentBytes() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0.0;
  return double(usage.ru_maxrss) * 1024.0;  // Linux reports kilobytes
}

bool TuneAllocatorForLargeArrays(bool override_environment) {
#if defined(__GLIBC__)
  const char* opt_out = std::getenv("AOSR_MALLOC_TUNING");
  if (opt_out && std::string(opt_out) == "0") return false;
  if (!override_environment) {
    const char* tunables = std::getenv("GLIBC_TUNABLES");
    if (tunables && std::string(tunables).find("glibc.malloc.") != std::string::npos) return false;
    for (const char* name : {"MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_"})
      if (std::getenv(name)) return false;
  }
  // Setting either threshold explicitly also turns glibc's dynamic adjustment off. M_MMAP_MAX = 0: blocks above
  // the threshold come from the heap too (the header says why); the threshold still applies where mmap is the
  // only way (a thread's arena asked for more than its heap holds).
  const bool mmap_ok = mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024) == 1;
  const bool trim_ok = mallopt(M_TRIM_THRESHOLD, 1024 * 1024 * 1024) == 1;
  const bool max_ok = mallopt(M_MMAP_MAX, 0) == 1;
  return mmap_ok && trim_ok && max_ok;
#else
  (void)override_environment;
  return false;
#endif
}

}  // namespace aosr
