// Live quick-look (include/aosr/solvers/quick_look.hpp): the directory watcher feeding the streaming
// reconstructor, one event per file.
#include "aosr/solvers/quick_look.hpp"

#include <chrono>
#include <future>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/io/fits.hpp"

namespace aosr {
namespace {

double NowUnix() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

double Since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

bool ValidKeyword(const std::string& k) {
  if (k.empty() || k.size() > 8) return false;
  for (char c : k)
    if (!((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_')) return false;
  return true;
}

}  // namespace

ViewOptions QuickLookOptions::DefaultQuickLookView() {
  ViewOptions v;
  v.stretch = Stretch::kAsinh;
  v.low_percentile = 0.5;
  v.high_percentile = 99.8;
  v.asinh_softening = 0.05;
  v.png_compression = 1;  // refreshed many times a second: speed over size
  return v;
}

bool QuickLookOptions::IsValid(std::string* why) const {
  auto bad = [why](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  std::string w;
  if (!video.IsValid(&w)) return bad("video." + w);
  if (!ValidKeyword(phase_key))
    return bad("phase_key = \"" + phase_key + "\"; allowed: 1-8 characters A-Z, 0-9, '-', '_' (a FITS keyword)");
  if (!time_key.empty() && !ValidKeyword(time_key))
    return bad("time_key = \"" + time_key + "\"; allowed: empty or 1-8 characters A-Z, 0-9, '-', '_'");
  if (!view.IsValid(&w)) return bad("view." + w);
  if (view.bits != 8 && view.bits != 16) return bad("view.bits = " + std::to_string(view.bits) + "; allowed: 8 or 16 (PNG)");
  if (!watch.IsValid(&w)) return bad("watch." + w);
  return true;
}

QuickLook::QuickLook(const std::string& directory, const Dataset& model, const QuickLookOptions& options)
    : options_(options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("QuickLook: options." + why);
  if (!options.output_dir.empty()) {
    std::error_code ec;
    if (!std::filesystem::is_directory(options.output_dir, ec))
      throw IoError(options.output_dir, "is not a directory (the quick-look's output folder must exist)");
  }
  video_ = std::make_unique<DatasetVideo>(model, options.video, options.problem);
  SetHrImageKeywords(model, "electron", &header_);
  slot_time_.assign(std::size_t(video_->slot_count()), -std::numeric_limits<double>::infinity());
  slot_file_.assign(std::size_t(video_->slot_count()), "");
  start_unix_s_ = NowUnix();
  // Last: the watcher's start is the zero point of "new" files.
  watcher_ = std::make_unique<DirectoryWatcher>(directory, options.watch);
}

QuickLook::~QuickLook() = default;

std::optional<QuickLookEvent> QuickLook::Next(double timeout_s) {
  CheckArgument(std::isfinite(timeout_s) && timeout_s >= 0, "QuickLook::Next", "timeout_s", timeout_s,
                "finite and >= 0");
  for (auto& a : watcher_->TakeAbandoned()) abandoned_.push_back(std::move(a));
  QuickLookEvent e;
  if (abandoned_.empty()) {
    std::optional<WatchedFile> f = watcher_->Next(timeout_s);
    for (auto& a : watcher_->TakeAbandoned()) abandoned_.push_back(std::move(a));
    if (!f && abandoned_.empty()) return std::nullopt;
    if (f) e = Process(*f);
  }
  if (e.file.empty()) {
    e.file = abandoned_.front().first;
    e.status = "incomplete";
    e.message = "never complete: " + abandoned_.front().second;
    abandoned_.erase(abandoned_.begin());
    ++incomplete_;
  }
  // The newest output goes in place unless a file is already waiting (top of quick_look.hpp).
  if (unwritten_ && !watcher_->Ready()) WriteLatest(&e);
  return e;
}

void QuickLook::WriteLatest(QuickLookEvent* e) {
  const auto t_write = std::chrono::steady_clock::now();
  if (!options_.output_dir.empty()) WriteOutputs(*unwritten_);
  e->write_s = Since(t_write);
  e->written_output = unwritten_->index;
  e->latency_s = NowUnix() - unwritten_mtime_;
  unwritten_.reset();
}

QuickLookEvent QuickLook::Process(const WatchedFile& f) {
  QuickLookEvent e;
  e.file = f.path;
  e.file_mtime_unix_s = f.mtime_unix_s;
  const auto t_read = std::chrono::steady_clock::now();
  auto reject = [&](const std::string& why) {
    e.status = "rejected";
    e.message = why;
    e.read_s = Since(t_read);
    ++rejected_;
    return e;
  };
  FitsData data;
  try {
    data = ReadFits(f.path);
  } catch (const std::exception& x) {
    return reject(x.what());
  }
  if (data.planes.size() != 1) return reject(std::to_string(data.planes.size()) + " planes; a frame is one 2-D image");
  const Image& frame = data.planes.front();
  const Shape lr = video_->frame_shape();
  if (ShapeOf(frame) != lr)
    return reject("shape " + ToString(ShapeOf(frame)) + "; the model's frames are " + ToString(lr));
  if (!data.header.Has(options_.phase_key)) return reject("no " + options_.phase_key + " keyword (the DM phase index)");
  long long slot = -1;
  try {
    slot = data.header.GetInt(options_.phase_key);
  } catch (const std::exception&) {
    return reject(options_.phase_key + " is not an integer");
  }
  if (slot < 0 || slot >= video_->slot_count())
    return reject(options_.phase_key + " = " + std::to_string(slot) + "; the model has phases 0.." +
                  std::to_string(video_->slot_count() - 1));
  e.slot = int(slot);
  if (options_.time_key.empty()) {
    e.time_s = f.mtime_unix_s - start_unix_s_;
  } else {
    if (!data.header.Has(options_.time_key)) return reject("no " + options_.time_key + " keyword (the frame's time)");
    try {
      e.time_s = data.header.GetDouble(options_.time_key);
    } catch (const std::exception&) {
      return reject(options_.time_key + " is not a number");
    }
    if (!std::isfinite(e.time_s)) return reject(options_.time_key + " is not finite");
  }
  e.read_s = Since(t_read);
  if (e.time_s < slot_time_[std::size_t(slot)]) {
    e.status = "late";
    e.message = "older than phase " + std::to_string(slot) + "'s current frame (" + slot_file_[std::size_t(slot)] +
                ", t = " + std::to_string(slot_time_[std::size_t(slot)]) + " s)";
    ++late_;
    return e;
  }
  const auto t_rec = std::chrono::steady_clock::now();
  try {
    e.output = video_->PushFrame(int(slot), used_, e.time_s, frame);
  } catch (const InvalidArgument& x) {
    return reject(x.what());  // e.g. non-finite pixels where the model's weight is positive
  }
  e.reconstruct_s = Since(t_rec);
  e.status = "used";
  e.frame = used_++;
  slot_time_[std::size_t(slot)] = e.time_s;
  slot_file_[std::size_t(slot)] = f.name;
  if (e.output) {
    ++outputs_;
    if (unwritten_) ++superseded_;
    unwritten_ = *e.output;
    unwritten_mtime_ = f.mtime_unix_s;
  }
  return e;
}

void QuickLook::WriteOutputs(const VideoFrame& out) {
  FitsHeader h = header_;
  h.Set("ORIGIN", std::string("aosr ") + AOSR_VERSION, "software that wrote this file");
  h.Set("METHOD", std::string(ToString(options_.video.method)), "reconstruction method");
  h.Set("WINDOW", std::string(ToString(options_.video.window)), "sliding: one output per frame; cycle: per cycle");
  h.Set("QLOUTPUT", (long long)out.index, "output number, 0-based");
  h.Set("QLTIME", out.time_s, "[s] time of the window's newest frame");
  h.Set("QLSTART", out.window_start_s, "[s] time of its oldest frame");
  h.Set("NPHASES", (long long)slot_file_.size(), "DM phases in the window");
  for (std::size_t s = 0; s < slot_file_.size() && s < 100; ++s) {  // QLFILE0..QLFILE99: 8-character names
    std::string name = slot_file_[s];
    if (name.size() > 60) name = "..." + name.substr(name.size() - 57);  // a FITS string holds 68 characters
    h.Set("QLFILE" + std::to_string(s), name, "frame of phase " + std::to_string(s));
  }
  const std::string dir = options_.output_dir;
  // The PNG (stretch and encoding, the larger part) on its own thread while this one writes the FITS file: two
  // independent files, each renamed into place when complete.
  std::future<void> png;
  if (options_.write_png)
    png = std::async(std::launch::async, [&] { WriteViewImage(dir + "/quicklook.png", out.image, options_.view); });
  try {
    WriteFits(dir + "/quicklook.fits", out.image, h, FitsType::kFloat32);
  } catch (...) {
    if (png.valid()) png.wait();
    throw;
  }
  if (png.valid()) png.get();  // rethrows the PNG's error
}

}  // namespace aosr
