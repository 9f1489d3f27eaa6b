#include "aosr/io/fits.hpp"

#include <fitsio.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/io/atomic_file.hpp"

namespace aosr {
namespace {

// ---------------------------------------------------------------------------------------------
// cfitsio plumbing

// Throws IoError(path, "<what>: <status text> (status N); <message stack>"), draining cfitsio's
// error-message stack so that stale messages do not leak into a later error.
[[noreturn]] void ThrowFits(const std::string& path, int status, const std::string& what) {
  char text[FLEN_STATUS] = {0};
  fits_get_errstatus(status, text);
  std::string message = what + ": " + text + " (cfitsio status " + std::to_string(status) + ")";
  char line[FLEN_ERRMSG] = {0};
  while (fits_read_errmsg(line)) message += std::string("; ") + line;
  throw IoError(path, message);
}

// cfitsio keeps one process-wide stack of messages, and pushes informational ones too (e.g. the
// card of every HIERARCH keyword written). Each public call starts and ends with an empty stack so
// that an error message holds only its own story.
void ClearFitsMessages() { fits_clear_errmsg(); }

// Owns an open fitsfile*; closes it (ignoring errors) if not closed explicitly.
class FitsFile {
 public:
  FitsFile() = default;
  FitsFile(const FitsFile&) = delete;
  FitsFile& operator=(const FitsFile&) = delete;
  ~FitsFile() {
    if (f_ != nullptr) {
      int status = 0;
      fits_close_file(f_, &status);
      char line[FLEN_ERRMSG];
      while (fits_read_errmsg(line)) {
      }
    }
  }
  fitsfile** out() { return &f_; }
  fitsfile* get() const { return f_; }
  // Closing flushes buffered data, so its failure (e.g. disk full) is a real error.
  void Close(const std::string& path) {
    int status = 0;
    fitsfile* f = f_;
    f_ = nullptr;
    if (fits_close_file(f, &status)) ThrowFits(path, status, "cannot close (flush) the file");
  }

 private:
  fitsfile* f_ = nullptr;
};

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

bool IsPrintableAscii(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return c >= 32 && c <= 126; });
}

// Fewest significant digits (15..17) that make `v` read back bit-exact through "%.*G".
int RoundTripDigits(double v) {
  for (int digits = 15; digits < 17; ++digits) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.*G", digits, v);
    if (std::strtod(buf, nullptr) == v) return digits;
  }
  return 17;
}

void WriteKeyword(fitsfile* f, const FitsKeyword& k, const std::string& path) {
  int status = 0;
  const char* name = k.name.c_str();
  const char* comment = k.comment.empty() ? nullptr : k.comment.c_str();
  if (const bool* b = std::get_if<bool>(&k.value)) {
    fits_update_key_log(f, name, *b ? 1 : 0, comment, &status);
  } else if (const long long* i = std::get_if<long long>(&k.value)) {
    fits_update_key_lng(f, name, static_cast<LONGLONG>(*i), comment, &status);
  } else if (const double* d = std::get_if<double>(&k.value)) {
    fits_update_key_dbl(f, name, *d, -RoundTripDigits(*d), comment, &status);
  } else {
    // The long-string call writes an ordinary card when the text fits, CONTINUE cards otherwise.
    fits_update_key_longstr(f, name, std::get<std::string>(k.value).c_str(), comment, &status);
  }
  if (status) ThrowFits(path, status, "cannot write keyword " + k.name);
}

// Parses one keyword's value text (as cfitsio returns it) into a FitsValue. `f` is needed for
// strings, which may continue over CONTINUE cards.
FitsValue ParseValue(fitsfile* f, const std::string& name, const std::string& text, const std::string& path) {
  char type = 0;
  int status = 0;
  fits_write_errmark();
  if (fits_get_keytype(text.c_str(), &type, &status)) {
    fits_clear_errmark();
    return text;  // Unrecognised form: keep the raw text.
  }
  switch (type) {
    case 'L':
      return text == "T";
    case 'I': {
      errno = 0;
      const long long v = std::strtoll(text.c_str(), nullptr, 10);
      if (errno != ERANGE) return v;
      return std::strtod(text.c_str(), nullptr);  // Too large for 64 bits.
    }
    case 'F': {
      std::string t = text;
      std::replace(t.begin(), t.end(), 'D', 'E');  // FITS allows a Fortran 'D' exponent.
      std::replace(t.begin(), t.end(), 'd', 'E');
      return std::strtod(t.c_str(), nullptr);
    }
    case 'C': {
      char* long_value = nullptr;
      if (fits_read_key_longstr(f, name.c_str(), &long_value, nullptr, &status)) {
        ThrowFits(path, status, "cannot read string keyword " + name);
      }
      std::string s = long_value;
      fits_free_memory(long_value, &status);
      return s;
    }
    default:
      return text;  // 'X' (complex) and anything newer: raw text.
  }
}

FitsHeader ReadHeader(fitsfile* f, const std::string& path) {
  int status = 0, count = 0, more = 0;
  if (fits_get_hdrspace(f, &count, &more, &status)) ThrowFits(path, status, "cannot read the header");
  FitsHeader header;
  for (int n = 1; n <= count; ++n) {
    char name[FLEN_KEYWORD] = {0}, value[FLEN_VALUE] = {0}, comment[FLEN_COMMENT] = {0};
    if (fits_read_keyn(f, n, name, value, comment, &status)) {
      ThrowFits(path, status, "cannot read header card " + std::to_string(n));
    }
    if (value[0] == '\0' || FitsHeader::IsStructural(name)) continue;
    header.Set(name, ParseValue(f, name, value, path), IsPrintableAscii(comment) ? comment : "");
  }
  return header;
}

struct ImageInfo {
  int bitpix = 0;
  std::vector<LONGLONG> axes;  // NAXIS1 (x), NAXIS2 (y)[, NAXIS3 (planes)]
};

// Moves to the first HDU holding image data (the primary HDU unless it is empty) and returns its
// BITPIX and axis lengths; IoError when there is none or it is not 2-D/3-D.
ImageInfo FindImage(fitsfile* f, const std::string& path) {
  int status = 0, hdus = 0;
  if (fits_get_num_hdus(f, &hdus, &status)) ThrowFits(path, status, "cannot count the HDUs");
  for (int h = 1; h <= hdus; ++h) {
    int type = 0;
    if (fits_movabs_hdu(f, h, &type, &status))
      ThrowFits(path, status, "cannot move to HDU " + std::to_string(h));
    if (type != IMAGE_HDU) continue;
    int bitpix = 0, naxis = 0;
    LONGLONG naxes[3] = {0, 0, 0};
    if (fits_get_img_paramll(f, 3, &bitpix, &naxis, naxes, &status)) {
      ThrowFits(path, status, "cannot read the image parameters of HDU " + std::to_string(h));
    }
    if (naxis == 0) continue;
    if (naxis < 2 || naxis > 3) {
      throw IoError(path, "HDU " + std::to_string(h) + " has NAXIS = " + std::to_string(naxis) +
                              "; aosr reads 2-D images and 3-D cubes only");
    }
    std::vector<LONGLONG> axes(naxes, naxes + naxis);
    if (std::find(axes.begin(), axes.end(), 0) != axes.end()) continue;  // Zero-length axis: no data.
    return {bitpix, axes};
  }
  throw IoError(path, "no image data in any of its " + std::to_string(hdus) + " HDU(s)");
}

// Copies the planes into one buffer in file order, converting to float32 if asked.
template <typename T>
std::vector<T> Flatten(const ImageStack& planes) {
  std::vector<T> out;
  out.reserve(planes.size() * static_cast<size_t>(planes.front().size()));
  for (const Image& p : planes) out.insert(out.end(), p.data(), p.data() + p.size());
  return out;
}

// Checks one HDU's planes before anything is written: non-empty, one shape, float32's range when asked.
void CheckPlanes(const char* function, const std::string& what, const ImageStack& planes, FitsType type) {
  const auto label = [&what](const std::string& x) { return what.empty() ? x : what + " " + x; };
  CheckArgument(!planes.empty(), function, label("planes"), "0 planes", "at least one plane");
  const Shape shape = ShapeOf(planes.front());
  CheckArgument(shape.size() > 0, function, label("image shape"), ToString(shape), "non-empty");
  for (size_t p = 0; p < planes.size(); ++p) {
    if (ShapeOf(planes[p]) != shape) {
      throw InvalidArgument(function, label("plane " + std::to_string(p) + " shape"), ToString(ShapeOf(planes[p])),
                            "the shape of plane 0, " + ToString(shape));
    }
  }
  if (type == FitsType::kFloat32) {
    for (const Image& p : planes) {
      for (Index i = 0; i < p.size(); ++i) {
        const double v = p.data()[i];
        if (std::isfinite(v) && std::abs(v) > FLT_MAX) {
          throw InvalidArgument(function, label("pixel value"), ToString(v),
                                "|v| <= 3.4e38 for float32 (write with FitsType::kFloat64)");
        }
      }
    }
  }
}

// Appends one image HDU (the primary one if the file is empty, else an IMAGE extension) to an open file:
// axes, the header's keywords (then EXTNAME when given), the pixels. The planes were checked.
void WriteHdu(fitsfile* f, const std::string& path, const ImageStack& planes, const FitsHeader& header,
              FitsType type, int naxis, const std::string& extname = "") {
  const Shape shape = ShapeOf(planes.front());
  int status = 0;
  LONGLONG axes[3] = {shape.cols, shape.rows, static_cast<LONGLONG>(planes.size())};  // x fastest.
  const int bitpix = type == FitsType::kFloat32 ? FLOAT_IMG : DOUBLE_IMG;
  if (fits_create_imgll(f, bitpix, naxis, axes, &status)) {
    ThrowFits(path, status, extname.empty() ? "cannot create the image HDU" : "cannot create extension " + extname);
  }
  for (const FitsKeyword& k : header.keywords()) WriteKeyword(f, k, path);
  if (!extname.empty()) WriteKeyword(f, {"EXTNAME", extname, "name of this extension"}, path);
  const LONGLONG n = static_cast<LONGLONG>(planes.size()) * shape.size();
  if (type == FitsType::kFloat32) {
    std::vector<float> data = Flatten<float>(planes);
    fits_write_img(f, TFLOAT, 1, n, data.data(), &status);
  } else {
    std::vector<double> data = Flatten<double>(planes);
    fits_write_img(f, TDOUBLE, 1, n, data.data(), &status);
  }
  if (status) ThrowFits(path, status, extname.empty() ? "cannot write the pixels" : "cannot write the pixels of " + extname);
}

void WriteCube(const char* function, const std::string& path, const ImageStack& planes,
               const FitsHeader& header, FitsType type, int naxis) {
  CheckPlanes(function, "", planes, type);
  AtomicWrite(path, [&](const std::string& tmp) {
    ClearFitsMessages();
    FitsFile file;
    int status = 0;
    if (fits_create_diskfile(file.out(), tmp.c_str(), &status)) ThrowFits(path, status, "cannot create");
    WriteHdu(file.get(), path, planes, header, type, naxis);
    file.Close(path);
    ClearFitsMessages();
  });
}

const FitsKeyword& Require(const FitsHeader& h, const std::string& name, const char* function) {
  const FitsKeyword* k = h.Find(name);
  if (k == nullptr) throw InvalidArgument(function, "keyword", name, "a keyword present in the header");
  return *k;
}

std::string TypeName(const FitsValue& v) {
  static const char* kNames[] = {"a logical", "an integer", "a real", "a string"};
  return kNames[v.index()];
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// FitsHeader

bool FitsHeader::IsStructural(const std::string& name) {
  const std::string n = Upper(name);
  static const char* kReserved[] = {"SIMPLE",  "BITPIX",   "NAXIS",   "EXTEND",   "BSCALE", "BZERO",
                                    "BLANK",   "XTENSION", "PCOUNT",  "GCOUNT",   "END",    "CHECKSUM",
                                    "DATASUM", "COMMENT",  "HISTORY", "CONTINUE", ""};
  for (const char* r : kReserved) {
    if (n == r) return true;
  }
  // NAXISn: NAXIS followed by digits only.
  return n.size() > 5 && n.compare(0, 5, "NAXIS") == 0 && std::all_of(n.begin() + 5, n.end(), [](char c) {
           return std::isdigit(static_cast<unsigned char>(c));
         });
}

void FitsHeader::Set(const std::string& name, const FitsValue& value, const std::string& comment) {
  const char* fn = "FitsHeader::Set";
  const std::string n = Upper(name);
  CheckArgument(!n.empty() && n.size() <= 60 && IsPrintableAscii(n) && n.find('=') == std::string::npos &&
                    n.front() != ' ' && n.back() != ' ',
                fn, "keyword name", "'" + name + "'",
                "1..60 printable ASCII characters without '=' or surrounding blanks");
  CheckArgument(!IsStructural(n), fn, "keyword name", n,
                "a user keyword (structural and commentary keywords are written by the writer)");
  if (const double* d = std::get_if<double>(&value)) {
    CheckArgument(std::isfinite(*d), fn, n + " value", *d,
                  "a finite number (FITS headers cannot hold NaN/Inf)");
  }
  if (const std::string* s = std::get_if<std::string>(&value)) {
    CheckArgument(IsPrintableAscii(*s), fn, n + " value", *s, "printable ASCII text");
  }
  CheckArgument(IsPrintableAscii(comment), fn, n + " comment", comment, "printable ASCII text");
  for (FitsKeyword& k : keywords_) {
    if (k.name == n) {
      k.value = value;
      k.comment = comment;
      return;
    }
  }
  keywords_.push_back({n, value, comment});
}

void FitsHeader::Set(const std::string& name, bool value, const std::string& comment) {
  Set(name, FitsValue(value), comment);
}
void FitsHeader::Set(const std::string& name, int value, const std::string& comment) {
  Set(name, FitsValue(static_cast<long long>(value)), comment);
}
void FitsHeader::Set(const std::string& name, long value, const std::string& comment) {
  Set(name, FitsValue(static_cast<long long>(value)), comment);
}
void FitsHeader::Set(const std::string& name, long long value, const std::string& comment) {
  Set(name, FitsValue(value), comment);
}
void FitsHeader::Set(const std::string& name, double value, const std::string& comment) {
  Set(name, FitsValue(value), comment);
}
void FitsHeader::Set(const std::string& name, const char* value, const std::string& comment) {
  Set(name, FitsValue(std::string(value)), comment);
}
void FitsHeader::Set(const std::string& name, const std::string& value, const std::string& comment) {
  Set(name, FitsValue(value), comment);
}

const FitsKeyword* FitsHeader::Find(const std::string& name) const {
  const std::string n = Upper(name);
  for (const FitsKeyword& k : keywords_) {
    if (k.name == n) return &k;
  }
  return nullptr;
}

bool FitsHeader::Has(const std::string& name) const { return Find(name) != nullptr; }

double FitsHeader::GetDouble(const std::string& name) const {
  const FitsKeyword& k = Require(*this, name, "FitsHeader::GetDouble");
  if (const double* d = std::get_if<double>(&k.value)) return *d;
  if (const long long* i = std::get_if<long long>(&k.value)) return static_cast<double>(*i);
  throw InvalidArgument("FitsHeader::GetDouble", "keyword " + k.name, TypeName(k.value),
                        "a real or an integer");
}

long long FitsHeader::GetInt(const std::string& name) const {
  const FitsKeyword& k = Require(*this, name, "FitsHeader::GetInt");
  if (const long long* i = std::get_if<long long>(&k.value)) return *i;
  throw InvalidArgument("FitsHeader::GetInt", "keyword " + k.name, TypeName(k.value), "an integer");
}

std::string FitsHeader::GetString(const std::string& name) const {
  const FitsKeyword& k = Require(*this, name, "FitsHeader::GetString");
  if (const std::string* s = std::get_if<std::string>(&k.value)) return *s;
  throw InvalidArgument("FitsHeader::GetString", "keyword " + k.name, TypeName(k.value), "a string");
}

bool FitsHeader::GetBool(const std::string& name) const {
  const FitsKeyword& k = Require(*this, name, "FitsHeader::GetBool");
  if (const bool* b = std::get_if<bool>(&k.value)) return *b;
  throw InvalidArgument("FitsHeader::GetBool", "keyword " + k.name, TypeName(k.value), "a logical");
}

// ---------------------------------------------------------------------------------------------
// Files

void WriteFits(const std::string& path, const Image& img, const FitsHeader& header, FitsType type) {
  WriteCube("WriteFits", path, ImageStack{img}, header, type, 2);
}

void WriteFitsCube(const std::string& path, const ImageStack& planes, const FitsHeader& header,
                   FitsType type) {
  WriteCube("WriteFitsCube", path, planes, header, type, 3);
}

namespace {

void CheckReadablePath(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(path, "no such file");
  if (std::filesystem::is_directory(path, ec)) throw IoError(path, "is a directory, not a FITS file");
  // A device or FIFO (/dev/zero) never ends: reading it would not either.
  if (!std::filesystem::is_regular_file(path, ec)) throw IoError(path, "is not a regular file (a device, FIFO or socket)");
}

void OpenForReading(FitsFile* file, const std::string& path) {
  CheckReadablePath(path);
  ClearFitsMessages();
  int status = 0;
  if (fits_open_diskfile(file->out(), path.c_str(), READONLY, &status)) {
    ThrowFits(path, status, "cannot open as FITS");
  }
}

// Reads the current HDU's image (described by `info`) and its header, after the memory and truncation checks.
FitsData ReadCurrentImage(fitsfile* f, const std::string& path, const ImageInfo& info) {
  int status = 0;
  const std::vector<LONGLONG>& axes = info.axes;
  const Index cols = axes[0], rows = axes[1];
  const Index planes = axes.size() == 3 ? axes[2] : 1;
  // Sizes come from the file: refuse what cannot fit before allocating, and an uncompressed HDU whose data
  // the file does not hold (a truncated file, or a header that lies) before reading.
  CheckMemory(8.0 * double(rows) * double(cols) * double(planes),
              path + ": a FITS image of " + std::to_string(planes) + " plane(s) of " + std::to_string(rows) + "x" +
                  std::to_string(cols) + " pixels");
  {
    int compressed = fits_is_compressed_image(f, &status);
    LONGLONG head = 0, data_start = 0, data_end = 0;
    if (!compressed && fits_get_hduaddrll(f, &head, &data_start, &data_end, &status) == 0) {
      std::error_code ec;
      const auto size = std::filesystem::file_size(path, ec);
      const double needed = double(std::abs(info.bitpix) / 8) * double(rows) * double(cols) * double(planes);
      // Only for a plain FITS file on disk (it starts "SIMPLE"); a gzip'd one is smaller than its data.
      char magic[6] = {};
      std::FILE* raw = std::fopen(path.c_str(), "rb");
      const bool plain = raw != nullptr && std::fread(magic, 1, 6, raw) == 6 && std::string(magic, 6) == "SIMPLE";
      if (raw != nullptr) std::fclose(raw);
      if (plain && !ec && double(data_start) + needed > double(size))
        throw IoError(path, "truncated: its header promises " + std::to_string(planes) + " plane(s) of " +
                                std::to_string(rows) + "x" + std::to_string(cols) + " pixels (BITPIX " +
                                std::to_string(info.bitpix) + ", " + FormatBytes(needed) + " of data) but the file holds " +
                                FormatBytes(std::max(0.0, double(size) - double(data_start))) + " after its header");
    }
    status = 0;
  }

  FitsData data;
  data.header = ReadHeader(f, path);
  data.planes.reserve(planes);
  // Integer data: pixels equal to BLANK become NaN. Float data: no null checking, because cfitsio
  // would treat every IEEE special value (Inf as well as NaN) as null; NaN and Inf pass unchanged.
  double nan = std::numeric_limits<double>::quiet_NaN();
  double* null_value = info.bitpix > 0 ? &nan : nullptr;
  for (Index p = 0; p < planes; ++p) {
    Image plane(rows, cols);
    int any_null = 0;
    if (fits_read_img(f, TDOUBLE, 1 + p * rows * cols, rows * cols, null_value, plane.data(), &any_null, &status)) {
      ThrowFits(path, status,
                "cannot read plane " + std::to_string(p) + " of " + std::to_string(planes) + " (" +
                    std::to_string(rows) + "x" + std::to_string(cols) + ")");
    }
    data.planes.push_back(std::move(plane));
  }
  return data;
}

// The EXTNAME of the current HDU, "" when it has none.
std::string CurrentExtname(fitsfile* f) {
  char value[FLEN_VALUE] = {0};
  int status = 0;
  fits_write_errmark();
  if (fits_read_key(f, TSTRING, "EXTNAME", value, nullptr, &status)) {
    fits_clear_errmark();
    return "";
  }
  return value;
}

}  // namespace

FitsData ReadFits(const std::string& path) {
  FitsFile file;
  OpenForReading(&file, path);
  const ImageInfo info = FindImage(file.get(), path);
  FitsData data = ReadCurrentImage(file.get(), path, info);
  file.Close(path);
  ClearFitsMessages();
  return data;
}

FitsImageInfo ReadFitsInfo(const std::string& path) {
  FitsFile file;
  OpenForReading(&file, path);
  const ImageInfo info = FindImage(file.get(), path);
  FitsImageInfo out;
  out.header = ReadHeader(file.get(), path);
  out.cols = info.axes[0];
  out.rows = info.axes[1];
  out.planes = info.axes.size() == 3 ? info.axes[2] : 1;
  file.Close(path);
  ClearFitsMessages();
  return out;
}

FitsData ReadFitsSection(const std::string& path, Index y0, Index x0, Index rows, Index cols) {
  FitsFile file;
  OpenForReading(&file, path);
  const ImageInfo info = FindImage(file.get(), path);
  const Index width = info.axes[0], height = info.axes[1];
  const Index planes = info.axes.size() == 3 ? info.axes[2] : 1;
  CheckArgument(y0 >= 0 && x0 >= 0 && rows >= 1 && cols >= 1 && y0 + rows <= height && x0 + cols <= width,
                "ReadFitsSection", "section",
                "rows [" + std::to_string(y0) + ", " + std::to_string(y0 + rows) + ") x cols [" + std::to_string(x0) +
                    ", " + std::to_string(x0 + cols) + ")",
                "inside the " + std::to_string(height) + "x" + std::to_string(width) + " image of " + path);
  FitsData data;
  data.header = ReadHeader(file.get(), path);
  // As ReadCurrentImage: BLANK becomes NaN for integer data; float data pass unchanged.
  double nan = std::numeric_limits<double>::quiet_NaN();
  double* null_value = info.bitpix > 0 ? &nan : nullptr;
  for (Index p = 0; p < planes; ++p) {
    Image plane(rows, cols);
    // FITS pixel coordinates are 1-based, x first; the section is inclusive at both ends.
    long first[3] = {long(x0 + 1), long(y0 + 1), long(p + 1)};
    long last[3] = {long(x0 + cols), long(y0 + rows), long(p + 1)};
    long step[3] = {1, 1, 1};
    int any_null = 0, status = 0;
    if (fits_read_subset(file.get(), TDOUBLE, first, last, step, null_value, plane.data(), &any_null, &status))
      ThrowFits(path, status, "cannot read the section rows " + std::to_string(y0) + ".." + std::to_string(y0 + rows - 1) +
                                  " x cols " + std::to_string(x0) + ".." + std::to_string(x0 + cols - 1) + " of plane " +
                                  std::to_string(p));
    data.planes.push_back(std::move(plane));
  }
  file.Close(path);
  ClearFitsMessages();
  return data;
}

std::vector<std::string> FitsExtensionNames(const std::string& path) {
  FitsFile file;
  OpenForReading(&file, path);
  int status = 0, hdus = 0;
  if (fits_get_num_hdus(file.get(), &hdus, &status)) ThrowFits(path, status, "cannot count the HDUs");
  std::vector<std::string> names;
  for (int h = 2; h <= hdus; ++h) {
    int type = 0;
    if (fits_movabs_hdu(file.get(), h, &type, &status)) ThrowFits(path, status, "cannot move to HDU " + std::to_string(h));
    const std::string name = CurrentExtname(file.get());
    if (!name.empty()) names.push_back(name);
  }
  file.Close(path);
  ClearFitsMessages();
  return names;
}

FitsData ReadFitsExtension(const std::string& path, const std::string& name) {
  CheckArgument(!name.empty(), "ReadFitsExtension", "name", "\"\"", "an EXTNAME");
  FitsFile file;
  OpenForReading(&file, path);
  int status = 0, hdus = 0;
  if (fits_get_num_hdus(file.get(), &hdus, &status)) ThrowFits(path, status, "cannot count the HDUs");
  // Walk the extensions ourselves: the match is case-insensitive and the error can list what is there.
  std::vector<std::string> names;
  int found = 0;
  for (int h = 2; h <= hdus && !found; ++h) {
    int type = 0;
    if (fits_movabs_hdu(file.get(), h, &type, &status)) ThrowFits(path, status, "cannot move to HDU " + std::to_string(h));
    const std::string extname = CurrentExtname(file.get());
    if (extname.empty()) continue;
    names.push_back(extname);
    if (Upper(extname) == Upper(name)) {
      if (type != IMAGE_HDU) throw IoError(path, "extension " + extname + " is a table, not an image");
      found = h;
    }
  }
  if (!found) {
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
    throw IoError(path, "no extension named " + name + " (its extensions: " + (list.empty() ? "none" : list) + ")");
  }
  int bitpix = 0, naxis = 0;
  LONGLONG naxes[3] = {0, 0, 0};
  if (fits_get_img_paramll(file.get(), 3, &bitpix, &naxis, naxes, &status))
    ThrowFits(path, status, "cannot read the image parameters of extension " + name);
  if (naxis < 2 || naxis > 3)
    throw IoError(path, "extension " + name + " has NAXIS = " + std::to_string(naxis) +
                            "; aosr reads 2-D images and 3-D cubes only");
  std::vector<LONGLONG> axes(naxes, naxes + naxis);
  if (std::find(axes.begin(), axes.end(), 0) != axes.end()) throw IoError(path, "extension " + name + " holds no data");
  FitsData data = ReadCurrentImage(file.get(), path, {bitpix, axes});
  file.Close(path);
  ClearFitsMessages();
  return data;
}

void WriteFitsWithExtensions(const std::string& path, const Image& primary, const FitsHeader& header,
                             const std::vector<FitsExtension>& extensions, FitsType type) {
  WriteFitsCubeWithExtensions(path, ImageStack{primary}, header, extensions, type);
}

void WriteFitsCubeWithExtensions(const std::string& path, const ImageStack& primary, const FitsHeader& header,
                                 const std::vector<FitsExtension>& extensions, FitsType type) {
  const char* fn = primary.size() == 1 ? "WriteFitsWithExtensions" : "WriteFitsCubeWithExtensions";
  CheckPlanes(fn, "primary", primary, type);
  std::vector<std::string> seen;
  for (size_t e = 0; e < extensions.size(); ++e) {
    const FitsExtension& x = extensions[e];
    const std::string label = "extension " + std::to_string(e);
    CheckArgument(!x.name.empty() && x.name.size() <= 68 && IsPrintableAscii(x.name) &&
                      x.name.find('\'') == std::string::npos && x.name.front() != ' ',
                  fn, label + " name", "'" + x.name + "'", "1..68 printable ASCII characters without quotes");
    const std::string upper = Upper(x.name);
    CheckArgument(std::find(seen.begin(), seen.end(), upper) == seen.end(), fn, label + " name", x.name,
                  "a name not used by another extension (EXTNAME is matched ignoring case)");
    seen.push_back(upper);
    if (const FitsKeyword* k = x.header.Find("EXTNAME")) {
      const std::string* v = std::get_if<std::string>(&k->value);
      CheckArgument(v != nullptr && *v == x.name, fn, "extension " + x.name + " header EXTNAME",
                    v ? *v : std::string("(not a string)"), "absent or equal to the extension's name");
    }
    CheckPlanes(fn, "extension " + x.name, x.planes, x.type);
  }
  AtomicWrite(path, [&](const std::string& tmp) {
    ClearFitsMessages();
    FitsFile file;
    int status = 0;
    if (fits_create_diskfile(file.out(), tmp.c_str(), &status)) ThrowFits(path, status, "cannot create");
    WriteHdu(file.get(), path, primary, header, type, primary.size() == 1 ? 2 : 3);
    for (const FitsExtension& x : extensions) {
      FitsHeader h;
      for (const FitsKeyword& k : x.header.keywords())
        if (k.name != "EXTNAME") h.Set(k.name, k.value, k.comment);
      WriteHdu(file.get(), path, x.planes, h, x.type, x.planes.size() == 1 ? 2 : 3, x.name);
    }
    file.Close(path);
    ClearFitsMessages();
  });
}

namespace {
// The reserved header space of a FitsRowWriter's primary HDU, in keywords: a reconstruction's header with WCS
// and the linear method's summary holds about 60.
constexpr int kFitsRowWriterHeaderKeywords = 400;

// What FitsRowWriter and FitsCubeWriter share: a temporary file next to `path` (renamed onto it when finished)
// holding one image HDU of `axes` (NAXIS1 first) with header space reserved. Nothing is left behind if it throws.
void* CreateTemporaryImage(const std::string& path, const char* tag, LONGLONG* axes, int naxis, FitsType type,
                           std::string* tmp) {
  const std::filesystem::path p(path);
  const std::filesystem::path dir = p.parent_path().empty() ? std::filesystem::path(".") : p.parent_path();
  if (!std::filesystem::is_directory(dir)) throw IoError(path, "its folder does not exist");
  static std::atomic<unsigned> counter{0};
  *tmp = path + ".tmp-" + std::to_string(::getpid()) + "-" + tag + std::to_string(counter++);
  ClearFitsMessages();
  fitsfile* f = nullptr;
  int status = 0;
  if (fits_create_diskfile(&f, tmp->c_str(), &status)) ThrowFits(path, status, "cannot create");
  const int bitpix = type == FitsType::kFloat32 ? FLOAT_IMG : DOUBLE_IMG;
  if (fits_create_imgll(f, bitpix, naxis, axes, &status) ||
      fits_set_hdrsize(f, kFitsRowWriterHeaderKeywords, &status)) {
    int ignored = 0;
    fits_close_file(f, &ignored);
    std::error_code ec;
    std::filesystem::remove(*tmp, ec);  // a throwing constructor runs no destructor
    ThrowFits(path, status, "cannot create the image HDU and its header space");
  }
  ClearFitsMessages();
  return f;
}

// An unfinished writer's end: the file closed and the temporary removed.
void AbandonTemporaryImage(void* file, const std::string& tmp) {
  if (file != nullptr) {
    int status = 0;
    fits_close_file(static_cast<fitsfile*>(file), &status);
    ClearFitsMessages();
  }
  if (!tmp.empty()) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
  }
}
}  // namespace

FitsRowWriter::FitsRowWriter(const std::string& path, Shape shape, FitsType type)
    : path_(path), shape_(shape), type_(type) {
  CheckArgument(shape.rows > 0 && shape.cols > 0, "FitsRowWriter", "shape", ToString(shape), "non-empty");
  LONGLONG axes[2] = {shape.cols, shape.rows};
  file_ = CreateTemporaryImage(path, "rows", axes, 2, type, &tmp_);
}

FitsRowWriter::~FitsRowWriter() { AbandonTemporaryImage(file_, tmp_); }

void FitsRowWriter::WriteRows(Index row0, const Image& rows) {
  CheckArgument(file_ != nullptr, "FitsRowWriter::WriteRows", "state", "finished", "a writer not yet finished");
  CheckArgument(rows.cols() == shape_.cols && row0 >= 0 && row0 + rows.rows() <= shape_.rows,
                "FitsRowWriter::WriteRows", "rows", std::to_string(rows.rows()) + " x " + std::to_string(rows.cols()) +
                " at row " + std::to_string(row0), "rows inside the " + ToString(shape_) + " image");
  if (rows.size() == 0) return;
  CheckPlanes("FitsRowWriter::WriteRows", "", ImageStack{rows}, type_);
  // Images are row-major (image.hpp), as FITS stores them (x fastest): the block is contiguous.
  LONGLONG first[2] = {1, LONGLONG(row0) + 1};
  const LONGLONG n = LONGLONG(rows.size());
  int status = 0;
  ClearFitsMessages();
  if (type_ == FitsType::kFloat32) {
    std::vector<float> data = Flatten<float>(ImageStack{rows});
    fits_write_pixll(static_cast<fitsfile*>(file_), TFLOAT, first, n, data.data(), &status);
  } else {
    std::vector<double> data = Flatten<double>(ImageStack{rows});
    fits_write_pixll(static_cast<fitsfile*>(file_), TDOUBLE, first, n, data.data(), &status);
  }
  if (status) ThrowFits(path_, status, "cannot write rows " + std::to_string(row0) + " to " +
                                           std::to_string(row0 + rows.rows() - 1));
  ClearFitsMessages();
}

void FitsRowWriter::Finish(const FitsHeader& header, const std::vector<FitsExtension>& extensions) {
  CheckArgument(file_ != nullptr, "FitsRowWriter::Finish", "state", "finished", "a writer not yet finished");
  fitsfile* f = static_cast<fitsfile*>(file_);
  ClearFitsMessages();
  for (const FitsKeyword& k : header.keywords()) WriteKeyword(f, k, path_);
  for (const FitsExtension& x : extensions) {
    CheckPlanes("FitsRowWriter::Finish", "extension " + x.name, x.planes, x.type);
    FitsHeader h;
    for (const FitsKeyword& k : x.header.keywords())
      if (k.name != "EXTNAME") h.Set(k.name, k.value, k.comment);
    WriteHdu(f, path_, x.planes, h, x.type, x.planes.size() == 1 ? 2 : 3, x.name);
  }
  int status = 0;
  file_ = nullptr;
  if (fits_close_file(f, &status)) ThrowFits(path_, status, "cannot close (flush) the file");
  ClearFitsMessages();
  std::error_code ec;
  std::filesystem::rename(tmp_, path_, ec);
  if (ec) throw IoError(path_, "cannot rename " + tmp_ + " onto it: " + ec.message());
  tmp_.clear();
}

FitsCubeWriter::FitsCubeWriter(const std::string& path, Shape plane, Index reserve_planes, FitsType type)
    : path_(path), plane_(plane), type_(type) {
  CheckArgument(plane.rows > 0 && plane.cols > 0, "FitsCubeWriter", "plane", ToString(plane), "non-empty");
  CheckArgument(reserve_planes >= 0, "FitsCubeWriter", "reserve_planes", reserve_planes, ">= 0");
  capacity_ = std::max<Index>(1, reserve_planes);
  LONGLONG axes[3] = {plane.cols, plane.rows, LONGLONG(capacity_)};
  file_ = CreateTemporaryImage(path, "cube", axes, 3, type, &tmp_);
}

FitsCubeWriter::~FitsCubeWriter() { AbandonTemporaryImage(file_, tmp_); }

// The primary HDU is the file's only one until Finish: resizing it moves nothing (growing pads with zeros
// that the next planes overwrite; cutting truncates).
void FitsCubeWriter::Resize(Index planes, int naxis) {
  LONGLONG axes[3] = {plane_.cols, plane_.rows, LONGLONG(planes)};
  int status = 0;
  const int bitpix = type_ == FitsType::kFloat32 ? FLOAT_IMG : DOUBLE_IMG;
  if (fits_resize_imgll(static_cast<fitsfile*>(file_), bitpix, naxis, axes, &status))
    ThrowFits(path_, status, "cannot resize the cube to " + std::to_string(planes) + " planes");
}

void FitsCubeWriter::Append(const Image& plane) {
  constexpr const char* kFn = "FitsCubeWriter::Append";
  CheckArgument(file_ != nullptr, kFn, "state", "finished", "a writer not yet finished");
  CheckArgument(ShapeOf(plane) == plane_, kFn, "plane " + std::to_string(planes_) + " shape", ToString(ShapeOf(plane)),
                "the cube's plane shape " + ToString(plane_));
  ClearFitsMessages();
  if (planes_ == capacity_) {
    capacity_ = std::max(2 * capacity_, planes_ + 1);
    Resize(capacity_, 3);
  }
  LONGLONG first[3] = {1, 1, LONGLONG(planes_) + 1};
  const LONGLONG n = LONGLONG(plane.size());
  int status = 0;
  if (type_ == FitsType::kFloat32) {
    buffer_.resize(std::size_t(n));
    for (Index i = 0; i < plane.size(); ++i) {
      const double v = plane.data()[i];
      if (std::isfinite(v) && std::abs(v) > FLT_MAX)
        throw InvalidArgument(kFn, "plane " + std::to_string(planes_) + " pixel value", ToString(v),
                              "|v| <= 3.4e38 for float32 (write with FitsType::kFloat64)");
      buffer_[std::size_t(i)] = static_cast<float>(v);
    }
    fits_write_pixll(static_cast<fitsfile*>(file_), TFLOAT, first, n, buffer_.data(), &status);
  } else {
    fits_write_pixll(static_cast<fitsfile*>(file_), TDOUBLE, first, n, const_cast<double*>(plane.data()), &status);
  }
  if (status) ThrowFits(path_, status, "cannot write plane " + std::to_string(planes_));
  ++planes_;
  ClearFitsMessages();
}

void FitsCubeWriter::Finish(const FitsHeader& header, const std::vector<FitsExtension>& extensions) {
  constexpr const char* kFn = "FitsCubeWriter::Finish";
  CheckArgument(file_ != nullptr, kFn, "state", "finished", "a writer not yet finished");
  CheckArgument(planes_ > 0, kFn, "planes", 0, "at least one plane appended");
  fitsfile* f = static_cast<fitsfile*>(file_);
  ClearFitsMessages();
  if (planes_ != capacity_ || planes_ == 1) Resize(planes_, planes_ == 1 ? 2 : 3);
  for (const FitsKeyword& k : header.keywords()) WriteKeyword(f, k, path_);
  for (const FitsExtension& x : extensions) {
    CheckPlanes(kFn, "extension " + x.name, x.planes, x.type);
    FitsHeader h;
    for (const FitsKeyword& k : x.header.keywords())
      if (k.name != "EXTNAME") h.Set(k.name, k.value, k.comment);
    WriteHdu(f, path_, x.planes, h, x.type, x.planes.size() == 1 ? 2 : 3, x.name);
  }
  int status = 0;
  file_ = nullptr;
  if (fits_close_file(f, &status)) ThrowFits(path_, status, "cannot close (flush) the file");
  ClearFitsMessages();
  std::error_code ec;
  std::filesystem::rename(tmp_, path_, ec);
  if (ec) throw IoError(path_, "cannot rename " + tmp_ + " onto it: " + ec.message());
  tmp_.clear();
}

Image ReadFitsImage(const std::string& path) {
  FitsData data = ReadFits(path);
  if (data.planes.size() != 1) {
    throw IoError(path, "expected a single image but found a cube of " + std::to_string(data.planes.size()) +
                            " planes of " + ToString(ShapeOf(data.planes.front())));
  }
  return std::move(data.planes.front());
}

}  // namespace aosr
