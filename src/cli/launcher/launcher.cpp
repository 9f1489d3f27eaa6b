// `aosr`, the command users type: a launcher with no library dependencies. It answers `aosr --version`,
// `aosr --help` and `aosr COMMAND --help` itself, from text the real program printed at build time
// (cmake/GenerateCliHelp.cmake writes aosr_cli_help.inc), and execs the real program, aosr-engine, for
// everything else, with the same arguments: exit status, stdout and stderr are the engine's own.
//
// Why: the engine links OpenImageIO (through it ~260 shared libraries), Ceres, OpenCV, cfitsio and FFTW, and
// the dynamic loader maps and relocates all of them before main() runs: ~0.4-0.6 s of wall time on this
// project's 2-core machine, paid by every completion, script loop and `--help`. The launcher starts in ~1 ms,
// and the exec adds ~1 ms to a real command. The help text cannot drift: it is regenerated from the engine
// whenever the engine is rebuilt, and tests/cli/startup_cli_test.cpp checks launcher == engine output for
// --version and every COMMAND --help.
//
// Where the engine is, relative to this executable's real path (symlinks resolved): the build tree's
// <dir>/libexec/aosr/aosr-engine, or an installed tree's <dir>/../libexec/aosr/aosr-engine (CMake install, a
// pip install into a virtualenv or the user site). AOSR_ENGINE overrides both. An installed tree that ships
// the data folder (<dir>/../share/aosr/data, as the pip package does) is passed to the engine as
// AOSR_DATA_DIR unless that is already set.
#include <limits.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

namespace {

struct HelpEntry {
  const char* command;  // "" for the top level
  const char* text;     // what `aosr [COMMAND] --help` prints
};

#include "aosr_cli_help.inc"  // kVersionText, kHelp[] (generated)

bool IsExecutable(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && access(path.c_str(), X_OK) == 0;
}

bool IsDirectory(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

// The folder of this executable's real path ("" if unknown).
std::string SelfDirectory() {
  char buf[PATH_MAX];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return "";
  buf[n] = '\0';
  std::string path(buf);
  const std::size_t slash = path.rfind('/');
  return slash == std::string::npos ? "" : path.substr(0, slash);
}

int Print(const char* text) {
  std::fputs(text, stdout);
  return std::fflush(stdout) == 0 ? 0 : 2;
}

// glibc's malloc settings for the engine, which only the environment a process starts with can give
// (GLIBC_TUNABLES): the thresholds core/memory.hpp's TuneAllocatorForLargeArrays would set with mallopt, and
// glibc.malloc.hugetlb=1, which asks the kernel for transparent huge pages on malloc's memory where THP is in
// "madvise" mode (as on this project's machines). The engine's image-sized arrays are then faulted in 2 MiB at a
// time instead of 4 KiB: a whole detector by tiles (8192², Tikhonov, 1 thread) took 13.4-14.0 s without and
// 9.0 s with, the same bytes and peak RSS (docs/development.md, stop 50). Not when the user chose malloc settings
// (GLIBC_TUNABLES with glibc.malloc.*, or MALLOC_*_ variables) or set AOSR_MALLOC_TUNING=0: the same rule as
// TuneAllocatorForLargeArrays, which then leaves the thresholds to these tunables.
void SetAllocatorTunables() {
  const char* opt_out = getenv("AOSR_MALLOC_TUNING");
  if (opt_out && std::strcmp(opt_out, "0") == 0) return;
  for (const char* name : {"MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_"})
    if (getenv(name)) return;
  const char* tunables = getenv("GLIBC_TUNABLES");
  if (tunables && std::strstr(tunables, "glibc.malloc.")) return;
  std::string value = "glibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold=33554432:"
                      "glibc.malloc.trim_threshold=1073741824:glibc.malloc.mmap_max=0";
  if (tunables && *tunables) value = std::string(tunables) + ":" + value;
  setenv("GLIBC_TUNABLES", value.c_str(), 1);
}

}  // namespace

int main(int argc, char** argv) {
  // The fast paths: exactly these argument lists (anything longer may be an error the engine must report).
  if (argc == 2 && std::strcmp(argv[1], "--version") == 0) return Print(kVersionText);
  const bool help_last =
      argc >= 2 && (std::strcmp(argv[argc - 1], "--help") == 0 || std::strcmp(argv[argc - 1], "-h") == 0);
  if (help_last && argc <= 3) {
    const char* command = argc == 3 ? argv[1] : "";
    for (const HelpEntry& e : kHelp)
      if (std::strcmp(e.command, command) == 0) return Print(e.text);
  }

  const std::string dir = SelfDirectory();
  std::string engine;
  if (const char* env = getenv("AOSR_ENGINE"); env && *env) {
    engine = env;
  } else {
    for (const std::string& candidate :
         {dir + "/libexec/aosr/aosr-engine", dir + "/../libexec/aosr/aosr-engine"})
      if (IsExecutable(candidate)) {
        engine = candidate;
        break;
      }
  }
  if (engine.empty()) {
    std::fprintf(stderr,
                 "aosr: internal error: the program aosr-engine is not installed beside this launcher (%s: "
                 "looked for libexec/aosr/aosr-engine and ../libexec/aosr/aosr-engine); set AOSR_ENGINE\n",
                 dir.c_str());
    return 2;
  }
  const char* data = getenv("AOSR_DATA_DIR");
  if (!(data && *data) && IsDirectory(dir + "/../share/aosr/data"))
    setenv("AOSR_DATA_DIR", (dir + "/../share/aosr/data").c_str(), 1);
  SetAllocatorTunables();
  execv(engine.c_str(), argv);
  std::fprintf(stderr, "aosr: internal error: cannot run %s: %s\n", engine.c_str(), std::strerror(errno));
  return 2;
}
