// What every fuzz target shares: a per-process scratch folder for the bytes under test, and the one rule of
// the boundary.
//
// ## The rule
//
// A loader given any bytes either returns or throws an aosr error (core/error.hpp: aosr::Error and its
// InvalidArgument, IoError, ResourceError, NumericalError). Each target calls its entry points through
// ExpectAosrErrors(), which swallows exactly those. Everything else escapes the target and is a finding:
//  * under libFuzzer an escaping exception reaches std::terminate -> abort, which libFuzzer reports as a crash;
//  * under the deterministic driver (driver.cpp) it is caught, printed with its type and message, and the
//    input is saved.
// Crashes, sanitizer reports and hangs are findings under both.
//
// ## Scratch files
//
// Most loaders take a path, so a target writes the input to a file in ScratchDir(): a folder per process
// under $TMPDIR (else /dev/shm, else /tmp), removed at exit. Targets that need companion files (the FITS files a
// dataset manifest names, a calibration set's frames) write them there once, at their first input.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "aosr/core/error.hpp"

namespace aosr::fuzz {

// This process's scratch folder (created at the first call, removed at normal exit).
inline const std::string& ScratchDir() {
  static const std::string dir = [] {
    namespace fs = std::filesystem;
    std::string base;
    if (const char* t = std::getenv("TMPDIR"); t != nullptr && *t != '\0') base = t;
    else if (fs::is_directory("/dev/shm")) base = "/dev/shm";
    else base = "/tmp";
    std::string tmpl = base + "/aosr-fuzz-" + std::to_string(::getpid()) + "-XXXXXX";
    if (::mkdtemp(tmpl.data()) == nullptr) {
      std::perror("aosr fuzz: mkdtemp");
      std::abort();
    }
    static const std::string made = tmpl;
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(made, ec);
    });
    return tmpl;
  }();
  return dir;
}

// Writes `size` bytes to ScratchDir()/name and returns the path.
inline std::string WriteScratch(const std::string& name, const uint8_t* data, size_t size) {
  const std::string path = ScratchDir() + "/" + name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  out.close();
  if (!out) {
    std::fprintf(stderr, "aosr fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
  return path;
}

inline std::string WriteScratch(const std::string& name, const std::string& text) {
  return WriteScratch(name, reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

// How many ExpectAosrErrors calls returned normally / with an aosr error (the driver prints them: a corpus
// whose inputs are all refused at the first check does not reach the code behind it).
inline uint64_t accepted_count = 0;
inline uint64_t refused_count = 0;
inline std::string last_refusal;  // the message of the last aosr error (driver --verbose prints them)

// Runs f(); an aosr error is the expected answer to bad input, anything else escapes (a finding).
template <typename F>
bool ExpectAosrErrors(F&& f) {
  try {
    f();
    ++accepted_count;
    return true;
  } catch (const aosr::Error& e) {
    ++refused_count;
    last_refusal = e.what();
    return false;
  }
}

}  // namespace aosr::fuzz
