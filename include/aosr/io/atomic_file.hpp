// Atomic file replacement and the "never overwrite an input" guard.
//
// Why: a crash, a full disk or an exception half-way through writing a FITS cube must not leave a
// truncated file where a good one was, nor a file that looks finished but is not. Every writer in
// aosr::io therefore writes to a temporary file in the destination's own directory and renames it
// over the destination only when the writer returned normally. On POSIX, rename(2) within one
// filesystem is atomic: readers see either the old file or the new one, never a mix. The temporary
// lives in the same directory (not /tmp) because a rename across filesystems is a copy, not atomic.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace aosr {

// Calls `writer(tmp_path)`, where tmp_path = path + ".tmp-<pid>-<counter>" is a fresh name in the
// same directory (unique within and across processes), then renames tmp_path onto `path`.
//  * The destination directory must exist: otherwise IoError naming `path` (nothing is created).
//  * If `writer` throws, the temporary file is removed and the exception is rethrown unchanged; an
//    existing file at `path` is left untouched.
//  * If `writer` returns without creating tmp_path, or the rename fails: IoError naming `path`.
// The writer must create tmp_path itself (it does not exist when the writer is called).
void AtomicWrite(const std::string& path, const std::function<void(const std::string& tmp_path)>& writer);

// Throws InvalidArgument if `output` names the same file as any of `inputs` once both are resolved
// with std::filesystem::weakly_canonical (so "a/../b.fits", "./b.fits" and a symlink to b.fits all
// match "b.fits"). Files that do not exist yet are compared by their normalised absolute paths.
// Called by command-line tools before writing: aosr never overwrites an input.
void CheckNotSameFile(const std::string& output, const std::vector<std::string>& inputs);

}  // namespace aosr
