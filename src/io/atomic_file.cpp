#include "aosr/io/atomic_file.hpp"

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <system_error>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

namespace fs = std::filesystem;

std::string TempPathFor(const std::string& path) {
  static std::atomic<unsigned long long> counter{0};
  return path + ".tmp-" + std::to_string(static_cast<long long>(::getpid())) + "-" +
         std::to_string(counter.fetch_add(1));
}

void RemoveQuietly(const std::string& path) {
  std::error_code ec;
  fs::remove(path, ec);  // Best effort: we are already reporting a more important error.
}

// weakly_canonical resolves the existing prefix (symlinks, "..") and normalises the rest.
fs::path Resolve(const std::string& p) {
  std::error_code ec;
  fs::path r = fs::weakly_canonical(fs::absolute(p, ec), ec);
  if (ec) r = fs::absolute(p).lexically_normal();
  return r;
}

}  // namespace

void AtomicWrite(const std::string& path, const std::function<void(const std::string& tmp_path)>& writer) {
  CheckArgument(!path.empty(), "AtomicWrite", "path", "\"\"", "a non-empty file name");
  fs::path dir = fs::path(path).parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw IoError(path, "cannot write: directory '" + dir.string() + "' does not exist");
  }
  if (fs::is_directory(path, ec)) throw IoError(path, "cannot write: the path is a directory");

  const std::string tmp = TempPathFor(path);
  try {
    writer(tmp);
  } catch (...) {
    RemoveQuietly(tmp);
    throw;
  }
  if (!fs::exists(tmp, ec)) throw IoError(path, "the writer did not create the temporary file " + tmp);
  fs::rename(tmp, path, ec);
  if (ec) {
    RemoveQuietly(tmp);
    throw IoError(path, "cannot rename temporary file " + tmp + ": " + ec.message());
  }
}

void CheckNotSameFile(const std::string& output, const std::vector<std::string>& inputs) {
  const fs::path out = Resolve(output);
  for (const std::string& in : inputs) {
    bool same = Resolve(in) == out;
    if (!same) {
      // Hard links (or differing spellings weakly_canonical cannot see through) share an inode.
      std::error_code ec;
      same = fs::exists(output, ec) && fs::exists(in, ec) && fs::equivalent(output, in, ec) && !ec;
    }
    if (same) {
      throw InvalidArgument("CheckNotSameFile: output '" + output + "' is the same file as input '" + in +
                            "'; aosr never overwrites an input");
    }
  }
}

}  // namespace aosr
