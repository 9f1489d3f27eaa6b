// Memory bounds: a size that a file, a config or an argument asks for is checked against an estimate of
// the memory it needs *before* anything is allocated, so that a scene asking for 1024 frames of 4096² pixels
// at r = 16 ends in a clear error ("needs about 1.1 TiB ... the limit is 23.4 GiB") instead of std::bad_alloc,
// the kernel's OOM killer, or a machine swapping for an hour.
//
// The limit (MemoryLimit) is, in order of precedence:
//   1. SetMemoryLimitBytes(bytes) in this process (the CLI's --memory-limit);
//   2. the environment variable AOSR_MEMORY_LIMIT: bytes, or a number with a K, M, G or T suffix (powers
//      of 1024), e.g. "8G";
//   3. the machine: the physical memory, or, when the process runs under an address-space limit
//      (`ulimit -v`, RLIMIT_AS) or a data limit (RLIMIT_DATA), what that limit leaves beyond the address
//      space the process already maps (shared libraries, thread stacks), whichever is smallest.
//
// Estimates are of the peak of the large arrays an operation holds at once (images, cubes, spectra, PSF
// stacks), in bytes, as doubles so that absurd products (1e6 frames x 65536² pixels) do not overflow. They
// leave out small and fixed costs, so the check stops requests that cannot fit, not ones that fit tightly.
#pragma once

#include <cstdint>
#include <string>

namespace aosr {

struct MemoryLimit {
  double bytes = 0.0;  // the limit
  std::string source;  // where it comes from, for messages: "AOSR_MEMORY_LIMIT=8G", "physical memory", ...
};

// The limit in force now (see the top of the file).
MemoryLimit CurrentMemoryLimit();

// Sets the limit for this process; 0 returns to the environment's or the machine's.
void SetMemoryLimitBytes(double bytes);

// Parses "123", "512M", "8G", "1.5T" (powers of 1024) into bytes; InvalidArgument naming `what` otherwise.
double ParseByteSize(const std::string& text, const std::string& what);

// "1.5 GiB", "320 MiB", "12 KiB", "800 B".
std::string FormatBytes(double bytes);

// Throws ResourceError (error.hpp) when `bytes` exceeds the current limit:
//   "<what> needs about <bytes> of memory (estimate), more than the limit of <limit> (<source>); ..."
// `what` names the request with its sizes, e.g. "scene.json: 1024 frames of 4096x4096 at r = 16".
// NaN and Inf estimates are refused as well (they come from absurd sizes).
void CheckMemory(double bytes, const std::string& what);

// The peak resident set size of this process so far, in bytes (getrusage), for reports and benchmarks.
double PeakResidentBytes();

// Tunes glibc's allocator for a process that allocates and frees image-sized arrays (MiB to tens of MiB)
// many times a second: solver temporaries, and Ceres's L-BFGS, which makes new vectors every iteration.
// glibc's defaults adapt the mmap and trim thresholds to the largest block freed so far and then hand the
// heap's free top back to the kernel whenever it exceeds twice that, so each such array is page-faulted in
// again on its next use: at r = 8 (1024^2) that was 25-30 % of a MAP reconstruction's time (1.6 s of system
// time in 4.9 s). Fixed thresholds (trim above 1 GiB) and no mmap for the main heap's blocks keep freed blocks
// for reuse. (A block above the mmap threshold, 32 MiB at most in glibc, is mapped and unmapped on every
// allocation: a 2176^2 HR window's arrays are 38 MiB, and with the threshold alone weighted Tikhonov on it spent
// 13.4 of its 39.5 CPU-s in the kernel and took 24.2 s; with mmap off, 1.4 CPU-s and 14.1 s.) The cost is that
// the process's resident size stays near its peak instead of shrinking between steps. The CLI, the benchmarks and the Python module call it at start; it does nothing
// when the user already chose malloc settings (GLIBC_TUNABLES with glibc.malloc.*, or MALLOC_*_ variables)
// or set AOSR_MALLOC_TUNING=0, and outside glibc. Returns whether it changed the settings.
// override_environment ignores the malloc variables (not AOSR_MALLOC_TUNING=0): for processes whose
// environment a framework set, not the user. Dask's nanny starts every worker with MALLOC_TRIM_THRESHOLD_=65536
// (distributed.nanny.pre-spawn-environ), which hands every freed image back to the kernel; aosr.distributed's
// tasks override it (bench/results/python.md measures the difference).
bool TuneAllocatorForLargeArrays(bool override_environment = false);

}  // namespace aosr
