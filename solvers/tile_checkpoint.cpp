// The finished tiles of a tiled run on disk (tile_checkpoint.hpp): a fingerprint of the run and an exact,
// versioned binary form of one tile's Reconstruction.
#include "tile_checkpoint.hpp"

#include <cstring>
#include <fstream>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/io/atomic_file.hpp"

namespace aosr::tiling_internal {
namespace {

constexpr char kTileMagic[8] = {'A', 'O', 'S', 'R', 'T', 'I', 'L', '1'};

// FNV-1a, 64 bits, over bytes in a fixed order (the fingerprint: not a security hash, a guard against mixing
// two runs' tiles by mistake).
struct TileFnv {
  std::uint64_t h = 1469598103934665603ull;
  void Bytes(const void* p, std::size_t n) {
    const unsigned char* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
  }
  template <class T>
  void Value(const T& v) {
    Bytes(&v, sizeof v);
  }
  void String(const std::string& s) {
    Value(s.size());
    Bytes(s.data(), s.size());
  }
  void Array(const Image& a) {
    Value(a.rows());
    Value(a.cols());
    Bytes(a.data(), sizeof(double) * a.size());
  }
  // A word at a time (8x fewer steps than Bytes: a tile's window data is tens of MB), with a shift that carries
  // the product's high bits down so that a change anywhere in a word reaches every bit of the hash.
  void Word(double v) {
    std::uint64_t w;
    std::memcpy(&w, &v, sizeof w);
    h = (h ^ w) * 1099511628211ull;
    h ^= h >> 29;
  }
};

// A little-endian-as-in-memory writer/reader of the fields (the file is read back by the same build), straight to
// and from the file: a tile's arrays are tens of MB at 8192², and large stream reads and writes go between the
// file and the arrays' own memory with no intermediate buffer.
struct TileWriter {
  std::ostream& out;
  void Bytes(const void* p, std::size_t n) {
    if (n > 0) out.write(static_cast<const char*>(p), std::streamsize(n));
  }
  template <class T>
  void Value(const T& v) {
    Bytes(&v, sizeof v);
  }
  void String(const std::string& s) {
    Value(std::uint64_t(s.size()));
    Bytes(s.data(), s.size());
  }
  void Array(const Image& a) {
    Value(std::int64_t(a.rows()));
    Value(std::int64_t(a.cols()));
    Bytes(a.data(), sizeof(double) * a.size());
  }
};

struct TileReader {
  std::istream& in;
  std::uint64_t size = 0;  // the file's
  std::uint64_t at = 0;
  bool ok = true;
  std::uint64_t left() const { return size - at; }
  void Bytes(void* p, std::size_t n) {
    if (!ok || n > left()) {
      ok = false;
      return;
    }
    if (n == 0) return;  // an empty array's data() may be null
    if (!in.read(static_cast<char*>(p), std::streamsize(n))) {
      ok = false;
      return;
    }
    at += n;
  }
  template <class T>
  T Value() {
    T v{};
    Bytes(&v, sizeof v);
    return v;
  }
  std::string String() {
    const std::uint64_t n = Value<std::uint64_t>();
    if (!ok || n > left()) {
      ok = false;
      return {};
    }
    std::string s(std::size_t(n), '\0');
    Bytes(s.data(), s.size());
    return s;
  }
  Image Array() {
    const std::int64_t rows = Value<std::int64_t>(), cols = Value<std::int64_t>();
    if (!ok || rows < 0 || cols < 0 || (cols > 0 && rows > std::int64_t(left() / sizeof(double)) / cols)) {
      ok = false;
      return {};
    }
    Image a(rows, cols);
    Bytes(a.data(), sizeof(double) * a.size());
    return a;
  }
};

[[noreturn]] void RefuseTile(const std::string& path, const std::string& why) {
  throw InvalidArgument("ReconstructTiled", "tiling.checkpoint_dir", path,
                        "a folder holding only this run's tiles (" + why +
                            "): empty the folder or give another one to start afresh");
}

}  // namespace

namespace {

void HashTileOptions(const ReconstructOptions& o, const TilingOptions& tiling, int overlap, TileFnv* fp) {
  TileFnv& f = *fp;
  f.Value(tiling.tile);
  f.Value(overlap);
  f.String(tiling.checkpoint_key);
  f.String(ToString(o.method));
  const TikhonovOptions& t = o.tikhonov;
  f.Value(int(t.prior)), f.Value(int(t.lambda_rule)), f.Value(t.lambda), f.Value(t.spectrum_slope);
  f.Value(t.spectrum_corner), f.Value(int(t.boundary)), f.Value(t.compute_std), f.Value(t.noise_sigma);
  f.Value(t.cg.max_iterations), f.Value(t.cg.tolerance);
  const TargetPsfOptions& l = o.linear;
  f.Value(int(l.kind)), f.Value(l.fwhm_hr_px), f.Array(l.image), f.Value(l.leakage), f.Value(l.kappa);
  f.Value(l.e_max);
  f.Value(l.noise_sigma), f.Value(l.compute_noise), f.Value(l.noise_probes), f.Value(l.seed);
  f.Value(o.auto_regularisation), f.Value(o.fixed_automatic.has_value());
  if (o.fixed_automatic) f.Value(o.fixed_automatic->pilot_lambda), f.Value(o.fixed_automatic->mu), f.Value(o.fixed_automatic->contrast);
  f.Value(o.tv.mu), f.Value(o.tv.positivity), f.Value(o.tv.max_iterations), f.Value(o.tv.relative_tolerance);
  f.Value(o.map.lambda), f.Value(int(o.map.prior)), f.Value(int(o.map.likelihood)), f.Value(int(o.map.positivity));
  f.Value(o.map.max_iterations), f.Value(o.map.read_noise);
  f.Value(int(o.drizzle.kernel)), f.Value(o.drizzle.pixfrac), f.Value(o.drizzle.fill_value);
}

}  // namespace

std::uint64_t RunFingerprint(const ReconstructionProblem& problem, const ReconstructOptions& o,
                             const TilingOptions& tiling, int overlap) {
  TileFnv f;
  f.String("aosr tiles v2");
  const MultiFrameModel& m = *problem.model;
  f.Value(m.hr_shape().rows);
  f.Value(m.hr_shape().cols);
  f.Value(m.r());
  for (int i = 0; i < m.frames(); ++i) {
    const ComplexImage& otf = m.otf(i);
    f.Bytes(otf.data(), sizeof(Complex) * otf.size());
  }
  for (const FrameOffset& off : problem.offsets) f.Value(off.dy), f.Value(off.dx);
  HashTileOptions(o, tiling, overlap, &f);
  return f.h;
}

std::uint64_t RunFingerprint(const FieldData& field, const ReconstructOptions& o, const TilingOptions& tiling,
                             int overlap) {
  TileFnv f;
  f.String("aosr field tiles v2");
  f.Value(field.lr.rows);
  f.Value(field.lr.cols);
  f.Value(field.r);
  for (const Image& k : field.kernels) f.Array(k);
  for (const FrameOffset& off : field.offsets) f.Value(off.dy), f.Value(off.dx);
  HashTileOptions(o, tiling, overlap, &f);
  return f.h;
}

std::uint64_t TileFingerprint(std::uint64_t run, const ImageStack& frames, const ImageStack& weights) {
  TileFnv f;
  f.h = run;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    // Only weighted pixels are data (a masked pixel may hold anything, NaN with any payload).
    const Image& a = frames[i];
    f.Value(a.rows()), f.Value(a.cols());
    for (Index k = 0; k < a.size(); ++k) {
      const bool on = weights.empty() || weights[i].data()[k] > 0;
      f.Word(on ? a.data()[k] : 0.0);
    }
  }
  for (const Image& w : weights) {
    f.Value(w.rows()), f.Value(w.cols());
    for (Index k = 0; k < w.size(); ++k) f.Word(w.data()[k]);
  }
  return f.h;
}

std::string TilePath(const std::string& dir, int index) {
  return dir + "/tile_" + std::to_string(index) + ".bin";
}

void WriteTile(const std::string& path, std::uint64_t fingerprint, int index, const Reconstruction& r,
               const std::vector<double>& misfit) {
  // Straight to the temporary file (AtomicWrite renames it into place once whole).
  AtomicWrite(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    TileWriter w{out};
    w.Bytes(kTileMagic, sizeof kTileMagic);
    w.Value(fingerprint);
    w.Value(std::int32_t(index));
    w.Array(r.image);
    w.Array(r.aux);
    w.String(r.aux_name);
    w.Value(r.regularisation);
    w.String(r.summary.method);
    w.Value(std::int32_t(r.summary.termination));
    w.String(r.summary.message);
    w.Value(std::int32_t(r.summary.iterations));
    w.Value(r.summary.final_cost);
    w.Array(r.effective_psf);
    w.Array(r.noise_correlation);
    w.Array(r.leakage_spectrum);
    w.Value(char(r.linear.has_value()));
    if (r.linear) {
      const TargetPsfSummary& s = *r.linear;
      w.String(s.method), w.Value(std::int32_t(s.termination)), w.String(s.message), w.String(s.target);
      for (double v : {s.target_fwhm_hr_px, s.effective_fwhm_hr_px, s.effective_psf_window_fraction, s.kappa, s.leakage,
                       s.leakage_unreachable, s.leakage_max_in_band, s.band_cycles_per_hr_px, s.dc_transfer,
                       s.noise_sigma, s.noise_rms, s.noise_rms_error, s.e_max})
        w.Value(v);
      w.Value(char(s.leakage_met)), w.Value(std::int64_t(s.unreachable_frequencies));
      w.Value(std::int32_t(s.noise_probes)), w.Value(char(s.fourier_exact));
    }
    // Appended last: files written before it was added end above and are read without it.
    w.Value(std::uint64_t(misfit.size()));
    for (double v : misfit) w.Value(v);
    out.flush();
    if (!out) throw IoError(tmp, "could not write the tile checkpoint");
  });
}

bool ReadTile(const std::string& path, std::uint64_t fingerprint, int index, Reconstruction* r,
              std::vector<double>* misfit) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return false;
  const std::streamoff size = in.tellg();
  in.seekg(0);
  if (size < 0 || !in) RefuseTile(path, "an unreadable tile file");
  TileReader rd{in, std::uint64_t(size)};
  char magic[sizeof kTileMagic];
  rd.Bytes(magic, sizeof magic);
  if (!rd.ok || std::memcmp(magic, kTileMagic, sizeof kTileMagic) != 0) RefuseTile(path, "not an aosr tile file");
  if (rd.Value<std::uint64_t>() != fingerprint) RefuseTile(path, "a tile of another run: other data or options");
  if (rd.Value<std::int32_t>() != index) RefuseTile(path, "the tile index differs from its name");
  Reconstruction t;
  t.image = rd.Array();
  t.aux = rd.Array();
  t.aux_name = rd.String();
  t.regularisation = rd.Value<double>();
  t.summary.method = rd.String();
  t.summary.termination = Termination(rd.Value<std::int32_t>());
  t.summary.message = rd.String();
  t.summary.iterations = rd.Value<std::int32_t>();
  t.summary.final_cost = rd.Value<double>();
  t.effective_psf = rd.Array();
  t.noise_correlation = rd.Array();
  t.leakage_spectrum = rd.Array();
  if (rd.Value<char>()) {
    TargetPsfSummary s;
    s.method = rd.String();
    s.termination = Termination(rd.Value<std::int32_t>());
    s.message = rd.String();
    s.target = rd.String();
    for (double* v : {&s.target_fwhm_hr_px, &s.effective_fwhm_hr_px, &s.effective_psf_window_fraction, &s.kappa,
                      &s.leakage, &s.leakage_unreachable, &s.leakage_max_in_band, &s.band_cycles_per_hr_px,
                      &s.dc_transfer, &s.noise_sigma, &s.noise_rms, &s.noise_rms_error, &s.e_max})
      *v = rd.Value<double>();
    s.leakage_met = rd.Value<char>() != 0;
    s.unreachable_frequencies = rd.Value<std::int64_t>();
    s.noise_probes = rd.Value<std::int32_t>();
    s.fourier_exact = rd.Value<char>() != 0;
    t.linear = s;
  }
  std::vector<double> m;
  if (rd.ok && rd.at < rd.size) {
    const std::uint64_t n = rd.Value<std::uint64_t>();
    if (rd.ok && n <= rd.left() / sizeof(double))
      for (std::uint64_t i = 0; i < n; ++i) m.push_back(rd.Value<double>());
    else
      rd.ok = false;
  }
  if (!rd.ok || rd.at != rd.size) RefuseTile(path, "a truncated or damaged tile file");
  if (misfit) *misfit = std::move(m);
  *r = std::move(t);
  return true;
}

}  // namespace aosr::tiling_internal
