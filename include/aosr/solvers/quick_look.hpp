// Live quick-look: a super-resolved image refreshed after each frame a camera writes into a directory (the seed
// paper's "real-time viewing"; `aosr watch`, aosr.watch in Python).
//
// The camera writes one FITS file per frame while the DM cycles through the N phases of a design. The model of
// the phases (their PSFs, the detector's gain, bias, mask and noise level) is a dataset taken or simulated with
// the same design: `model` below, as `aosr video` reads it. Each new file
//   1. is found complete by io/frame_watch.hpp (never read half-written);
//   2. is read: the primary HDU (or the first image extension when the primary has no data), a 2-D image of the
//      model's frame shape, raw counts (ADU), with its phase index (0..N−1) in the header keyword `phase_key`,
//      and its time in `time_key` (seconds) when one is named, else the file's modification time (seconds
//      since the quick-look started);
//   3. goes into the streaming reconstructor (solvers/video_stream.hpp) as the latest frame of its phase. With
//      the sliding window every frame after the first complete cycle gives an output from the latest frame of
//      each phase; a phase that is missing keeps its previous frame (VideoFrame::frames says which); a frame
//      older than its phase's current one (out of order) is reported "late" and not used;
//   4. when it completes an output: output_dir/quicklook.fits (float32, e⁻ per HR pixel, the HR grid's WCS,
//      the files used) and quicklook.png (the stretch of `view`, row 0 at the top as in aosr's video files) are
//      replaced atomically, so a viewer polling them never sees a partial image.
// Only the newest output is written: when another file is already waiting, writing is left to it (the output
// is "superseded"; the next written quick-look contains its frame, the window being sliding). Writing (~10 ms
// at 512²) costs more than an output of the slot filter (~2 ms), so a quick-look that fell behind (a burst of
// files, a busy machine) catches up instead of lagging further behind with every frame.
// Latency (QuickLookEvent::latency_s): from the completion (modification time, the wall clock) of the file that
// completed the output written, to the moment the quick-look was renamed into place (or, without output_dir,
// the output existed). It includes the watcher's detection, the read, the reconstruction and the writes.
//
// Nothing is lost silently: every file the watcher sees gives one event with a status (used, late, rejected,
// incomplete) and, for the last three, the reason.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "aosr/io/fits.hpp"
#include "aosr/io/frame_watch.hpp"
#include "aosr/io/image_io.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/video_stream.hpp"

namespace aosr {

struct QuickLookOptions {
  // The reconstruction (method, sliding or cycle window, λ/κ/μ rules; video_stream.hpp) and how the model
  // dataset's frames set the weights (dataset_problem.hpp).
  VideoOptions video;
  DatasetProblemOptions problem;
  // FITS keyword holding the frame's DM phase index, 0..N−1. Non-empty, at most 8 characters (FITS names).
  // DMPHASE: aosr's own writers and the tests; a camera's may differ.
  std::string phase_key = "DMPHASE";
  // FITS keyword holding the frame's time in seconds (any zero point; used for ordering and reported). Empty:
  // the file's modification time, in seconds since the QuickLook was made.
  std::string time_key;
  // Folder for quicklook.fits and quicklook.png (must exist). Empty: nothing is written (Python's iterator).
  std::string output_dir;
  bool write_png = true;
  // The PNG's display: asinh between the 0.5 and 99.8 percentiles of each output (levels follow the scene, as a
  // quick-look display should; the video file instead fixes them on its first frame).
  ViewOptions view = DefaultQuickLookView();
  DirectoryWatchOptions watch;

  static ViewOptions DefaultQuickLookView();
  bool IsValid(std::string* why) const;
};

struct QuickLookEvent {
  std::string file;       // the path
  std::string status;     // "used" | "late" | "rejected" | "incomplete"
  std::string message;    // why, for late, rejected and incomplete
  int frame = -1;         // used: 0-based number among the used frames
  int slot = -1;          // the phase index read from the header (when one was read)
  double time_s = 0;      // the frame's time (time_key, or seconds since start)
  std::optional<VideoFrame> output;  // the output this frame completed, if any
  double file_mtime_unix_s = 0;      // the file's completion
  int written_output = -1;  // the output put in place during this event (this frame's or a deferred one), or −1
  double latency_s = 0;     // for written_output: completion of its file → quick-look in place (top of the file)
  double read_s = 0, reconstruct_s = 0, write_s = 0;  // this frame's stages, wall seconds
};

class QuickLook {
 public:
  // Watches `directory` with `model` as the model of the phases (DatasetVideo's rules: frames, PSFs, weights).
  // InvalidArgument for options or a model the video engine refuses; IoError for a missing directory.
  QuickLook(const std::string& directory, const Dataset& model, const QuickLookOptions& options);
  ~QuickLook();

  // Processes the next file, waiting up to timeout_s for one; nullopt when none came. Errors in a file (not
  // FITS, wrong shape, no phase keyword, non-finite values) are events with status "rejected", not exceptions;
  // exceptions are for the output folder (IoError) only.
  std::optional<QuickLookEvent> Next(double timeout_s);

  int used() const { return used_; }
  int outputs() const { return outputs_; }
  int late() const { return late_; }
  int rejected() const { return rejected_; }
  int incomplete() const { return incomplete_; }
  int superseded() const { return superseded_; }  // outputs never written: a newer one was
  bool using_inotify() const { return watcher_->using_inotify(); }
  const DatasetVideo& video() const { return *video_; }

 private:
  QuickLookEvent Process(const WatchedFile& f);
  void WriteOutputs(const VideoFrame& out);
  void WriteLatest(QuickLookEvent* e);

  QuickLookOptions options_;
  FitsHeader header_;  // the model's HR keywords (BUNIT, WCS), the base of every quicklook.fits
  std::unique_ptr<DatasetVideo> video_;
  std::unique_ptr<DirectoryWatcher> watcher_;
  std::vector<double> slot_time_;        // time of each phase's current frame (−inf: none yet)
  std::vector<std::string> slot_file_;   // its file name
  std::vector<std::pair<std::string, std::string>> abandoned_;
  double start_unix_s_ = 0;
  std::optional<VideoFrame> unwritten_;  // the newest output, until written
  double unwritten_mtime_ = 0;           // its file's completion
  int used_ = 0, outputs_ = 0, late_ = 0, rejected_ = 0, incomplete_ = 0, superseded_ = 0;
};

}  // namespace aosr
