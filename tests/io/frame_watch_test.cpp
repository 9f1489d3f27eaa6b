// The live-frame watcher (frame_watch.hpp): the FITS length check against every truncation of real files (one
// and several HDUs), and the watcher with inotify and with scanning: files renamed into place, files written in
// place in two parts (reported once, only whole), names that are not frames, files present at the start, a file
// written again under the same name, and a file that never completes (given up and reported).
#include "aosr/io/frame_watch.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <thread>

#include "aosr/io/fits.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

struct TempDir {
  fs::path dir;
  explicit TempDir(const std::string& name) {
    dir = fs::temp_directory_path() / ("aosr_watch_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir / "watched");
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  std::string Watched(const std::string& name = "") const { return (dir / "watched" / name).string(); }
  std::string Staging(const std::string& name) const { return (dir / name).string(); }
};

std::string Bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void WriteBytes(const std::string& path, const std::string& bytes, std::ios::openmode mode = std::ios::trunc) {
  std::ofstream out(path, std::ios::binary | mode);
  out.write(bytes.data(), std::streamsize(bytes.size()));
}

// A frame file (17 × 23 float64, 3128 data bytes: a padded last block) and a two-HDU file.
void WriteFrame(const std::string& path, int phase) {
  FitsHeader h;
  h.Set("DMPHASE", phase);
  WriteFits(path, test::RandomImage({17, 23}, 5 + std::uint64_t(phase)), h, FitsType::kFloat64);
}

TEST(FitsFileIsComplete, EveryTruncationOfARealFileIsIncompleteAndTheWholeFileIsComplete) {
  TempDir t("complete");
  const std::string one = t.Staging("one.fits"), two = t.Staging("two.fits"), cut = t.Staging("cut.fits");
  WriteFrame(one, 1);
  FitsExtension e;
  e.name = "PSF";
  e.planes = {test::RandomImage({9, 9}, 3)};
  WriteFitsWithExtensions(two, test::RandomImage({8, 8}, 4), {}, {e});
  for (const std::string& path : {one, two}) {
    std::string why;
    EXPECT_TRUE(FitsFileIsComplete(path, &why)) << path << ": " << why;
    const std::string b = Bytes(path);
    ASSERT_EQ(b.size() % 2880, 0u);
    // Every block boundary and points inside the header, the data and the padding.
    for (std::size_t n : {std::size_t(1), std::size_t(80), std::size_t(2879), std::size_t(2880), std::size_t(2881),
                          b.size() / 2, b.size() - 2881, b.size() - 2880, b.size() - 1}) {
      // Cut exactly after a whole HDU the file is a valid FITS file of fewer HDUs: no reader can tell (which is
      // why writers of several HDUs must rename; frame_watch.hpp).
      if (n >= b.size() || n == b.find("XTENSION")) continue;
      WriteBytes(cut, b.substr(0, n));
      why.clear();
      EXPECT_FALSE(FitsFileIsComplete(cut, &why)) << path << " cut at " << n;
      EXPECT_FALSE(why.empty());
    }
  }
  // The second HDU's header cut short is named as such.
  const std::string b = Bytes(two);
  std::string why;
  WriteBytes(cut, b.substr(0, b.find("XTENSION") + 2880 - 1));
  EXPECT_FALSE(FitsFileIsComplete(cut, &why));
  EXPECT_THAT(why, HasSubstr("HDU 1"));
  WriteBytes(cut, std::string(5760, 'x'));
  EXPECT_FALSE(FitsFileIsComplete(cut, &why));
  EXPECT_THAT(why, HasSubstr("not a FITS file"));
  EXPECT_THAT(test::ErrorOf<IoError>([&] { FitsFileIsComplete(t.Staging("missing.fits")); }), HasSubstr("missing.fits"));
}

// Collects what the watcher reports within `seconds`.
std::vector<WatchedFile> Collect(DirectoryWatcher& w, double seconds) {
  std::vector<WatchedFile> out;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    const double left = std::chrono::duration<double>(end - std::chrono::steady_clock::now()).count();
    if (auto f = w.Next(std::max(0.0, left))) out.push_back(*f);
  }
  return out;
}

class WatcherModes : public ::testing::TestWithParam<bool> {};

TEST_P(WatcherModes, ReportsEachFileOnceAndOnlyWhole) {
  const bool inotify = GetParam();
  TempDir t(inotify ? "inotify" : "scan");
  WriteFrame(t.Watched("old.fits"), 0);  // present at the start: not reported
  DirectoryWatchOptions o;
  o.disable_inotify = !inotify;
  o.poll_interval_s = 0.05;
  DirectoryWatcher w(t.Watched(), o);
  EXPECT_EQ(w.using_inotify(), inotify);
  test::JoiningThread writer([&] {
    WriteFrame(t.Watched("a.fits"), 1);  // atomic: temporary name, then rename
    // In place, in two parts with the file closed in between (and a pause longer than a scan).
    WriteFrame(t.Staging("b.fits"), 2);
    const std::string b = Bytes(t.Staging("b.fits"));
    WriteBytes(t.Watched("b.FITS"), b.substr(0, b.size() / 2));
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    WriteBytes(t.Watched("b.FITS"), b.substr(b.size() / 2), std::ios::app);
    WriteBytes(t.Watched("notes.txt"), "not a frame");
    WriteBytes(t.Watched(".hidden.fits"), "editor's temporary");
    WriteFrame(t.Watched("c.fit"), 3);
  });
  const std::vector<WatchedFile> got = Collect(w, 1.2);
  writer.Join();
  std::vector<std::string> names;
  for (const WatchedFile& f : got) {
    names.push_back(f.name);
    std::string why;
    EXPECT_TRUE(FitsFileIsComplete(f.path, &why)) << f.name << ": reported before it was whole: " << why;
    EXPECT_EQ(f.bytes, fs::file_size(f.path));
    EXPECT_GE(f.complete_unix_s, f.mtime_unix_s - 1e-3);
  }
  EXPECT_EQ(names, (std::vector<std::string>{"a.fits", "b.FITS", "c.fit"}));
  // The same name written again is a new frame; an unchanged file is not reported twice.
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // a new modification time
  WriteFrame(t.Watched("a.fits"), 4);
  const std::vector<WatchedFile> again = Collect(w, 0.5);
  ASSERT_EQ(again.size(), 1u);
  EXPECT_EQ(again[0].name, "a.fits");
  EXPECT_TRUE(w.TakeAbandoned().empty());
}

INSTANTIATE_TEST_SUITE_P(InotifyAndScanning, WatcherModes, ::testing::Values(true, false),
                         [](const ::testing::TestParamInfo<bool>& i) { return i.param ? "Inotify" : "Scanning"; });

TEST(DirectoryWatcher, ExistingFilesComeFirstInNameOrder) {
  TempDir t("existing");
  WriteFrame(t.Watched("f2.fits"), 2);
  WriteFrame(t.Watched("f1.fits"), 1);
  DirectoryWatchOptions o;
  o.existing = true;
  DirectoryWatcher w(t.Watched(), o);
  const std::vector<WatchedFile> got = Collect(w, 0.2);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].name, "f1.fits");
  EXPECT_EQ(got[1].name, "f2.fits");
}

TEST(DirectoryWatcher, AFileThatNeverCompletesIsGivenUpAndReported) {
  TempDir t("abandon");
  DirectoryWatchOptions o;
  o.poll_interval_s = 0.05;
  o.abandon_after_s = 0.3;
  DirectoryWatcher w(t.Watched(), o);
  WriteFrame(t.Staging("s.fits"), 1);
  const std::string b = Bytes(t.Staging("s.fits"));
  WriteBytes(t.Watched("stuck.fits"), b.substr(0, 4000));
  EXPECT_TRUE(Collect(w, 0.8).empty());
  const auto gone = w.TakeAbandoned();
  ASSERT_EQ(gone.size(), 1u);
  EXPECT_THAT(gone[0].first, HasSubstr("stuck.fits"));
  EXPECT_THAT(gone[0].second, HasSubstr("written so far"));
  EXPECT_TRUE(w.TakeAbandoned().empty());
}

TEST(DirectoryWatcher, BadArgumentsAreNamed) {
  TempDir t("errors");
  EXPECT_THAT(test::ErrorOf<IoError>([&] { DirectoryWatcher w(t.Staging("nowhere")); }), HasSubstr("not a directory"));
  DirectoryWatchOptions o;
  o.poll_interval_s = 0;
  EXPECT_THAT(test::ErrorOf([&] { DirectoryWatcher w(t.Watched(), o); }), HasSubstr("poll_interval_s"));
  o = {};
  o.suffixes.clear();
  EXPECT_THAT(test::ErrorOf([&] { DirectoryWatcher w(t.Watched(), o); }), HasSubstr("suffixes"));
  DirectoryWatcher w(t.Watched());
  EXPECT_THAT(test::ErrorOf([&] { w.Next(-1); }), HasSubstr("timeout_s"));
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
