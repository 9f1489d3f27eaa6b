// FITS images and cubes (through cfitsio), with their header keywords.
//
// Orientation (the one rule that matters when opening our files in DS9 or astropy):
//   array element (y, x) = (row, column)  <->  FITS pixel (x + 1, y + 1), i.e. NAXIS1 = cols (x),
//   NAXIS2 = rows (y), NAXIS3 = planes. There is no flip: FITS stores NAXIS1 fastest, exactly as a
//   row-major array stores x fastest, so the bytes go out in memory order. Viewers draw FITS pixel
//   (1, 1) at the lower left, so our row 0 appears at the *bottom* in DS9 (and at the top of a PNG
//   written by WriteViewImage, which follows the image-file convention of row 0 on top).
//   astropy's fits.getdata() returns exactly our (y, x) array.
//
// Data:
//  * Written as IEEE float32 (BITPIX -32, the default: plenty for detector data and half the size)
//    or float64 (BITPIX -64, exact). A finite value beyond float32's range is refused rather than
//    silently written as Inf; choose kFloat64 for such data.
//  * NaN and Inf are written as they are: NaN is the FITS convention for a bad or missing pixel.
//  * Read from BITPIX 8/16/32/64/-32/-64; cfitsio applies BSCALE/BZERO, and integer pixels equal to
//    BLANK (undefined) become NaN. Everything is returned in double precision.
//
// Header:
//  * FitsHeader holds the user keywords in order. Names are case-insensitive and stored upper-case
//    (the FITS standard's form); names longer than 8 characters are written with the HIERARCH
//    convention by cfitsio. Strings longer than one card use the CONTINUE convention.
//  * Structural keywords are owned by the writer and are neither read into nor accepted by a
//    FitsHeader: SIMPLE, BITPIX, NAXIS, NAXISn, EXTEND, BSCALE, BZERO, BLANK, XTENSION, PCOUNT,
//    GCOUNT, END, CHECKSUM, DATASUM, plus the commentary keywords COMMENT, HISTORY, CONTINUE and
//    blank names (which carry no value). Keywords without a value are skipped on reading.
//  * Reading infers the type from the value's form: T/F -> bool, an integer -> long long (one too
//    large for 64 bits -> double), a real (E or D exponent) -> double, a quoted string -> string,
//    anything else (e.g. complex) -> its raw text as a string.
//  * Doubles are written with the fewest significant digits (15..17) that read back bit-exact.
//
// Errors: every cfitsio failure becomes aosr::IoError(path, cfitsio's status text and its message
// stack). Files are opened with cfitsio's "diskfile" calls, so '[', '(' and '!' in a path are plain
// characters rather than cfitsio's extended-filename syntax. Writes are atomic (AtomicWrite).
#pragma once

#include <string>
#include <variant>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr {

using FitsValue = std::variant<bool, long long, double, std::string>;

struct FitsKeyword {
  std::string name;  // Upper-case.
  FitsValue value;
  std::string comment;
};

class FitsHeader {
 public:
  // Adds a keyword, or replaces the value and comment of an existing one (keeping its position).
  // InvalidArgument for a structural/commentary name (see above), an empty name or one with
  // characters outside printable ASCII or containing '=', a non-finite double (FITS headers cannot
  // hold NaN/Inf), or a string with non-printable characters.
  // Overloads exist so that Set("K", 3) is an integer and Set("K", "text") is a string (a plain
  // std::variant would turn a const char* into a bool).
  void Set(const std::string& name, const FitsValue& value, const std::string& comment = "");
  void Set(const std::string& name, bool value, const std::string& comment = "");
  void Set(const std::string& name, int value, const std::string& comment = "");
  void Set(const std::string& name, long value, const std::string& comment = "");
  void Set(const std::string& name, long long value, const std::string& comment = "");
  void Set(const std::string& name, double value, const std::string& comment = "");
  void Set(const std::string& name, const char* value, const std::string& comment = "");
  void Set(const std::string& name, const std::string& value, const std::string& comment = "");

  bool Has(const std::string& name) const;
  // Typed access; InvalidArgument naming the keyword when it is missing or holds another type.
  // GetDouble also accepts an integer keyword (FITS writes 2.0 as "2." but others may write "2").
  double GetDouble(const std::string& name) const;
  long long GetInt(const std::string& name) const;
  std::string GetString(const std::string& name) const;
  bool GetBool(const std::string& name) const;
  // Nullptr when absent.
  const FitsKeyword* Find(const std::string& name) const;

  const std::vector<FitsKeyword>& keywords() const { return keywords_; }

  // True for the keywords that FitsHeader refuses (written by the writer itself, see above).
  static bool IsStructural(const std::string& name);

 private:
  std::vector<FitsKeyword> keywords_;
};

enum class FitsType { kFloat32, kFloat64 };

// Writes one 2-D image (NAXIS = 2) to `path`, replacing any existing file atomically.
// InvalidArgument for an empty image or (kFloat32) a finite value beyond float32's range.
void WriteFits(const std::string& path, const Image& img, const FitsHeader& header = {},
               FitsType type = FitsType::kFloat32);

// Writes planes as one cube (NAXIS = 3, NAXIS3 = planes.size()). All planes must have the same,
// non-empty shape; otherwise InvalidArgument.
void WriteFitsCube(const std::string& path, const ImageStack& planes, const FitsHeader& header = {},
                   FitsType type = FitsType::kFloat32);

struct FitsData {
  ImageStack planes;  // One plane for NAXIS = 2, NAXIS3 planes for NAXIS = 3.
  FitsHeader header;  // User keywords of the HDU the data came from.
};

// One named image extension (XTENSION = 'IMAGE', EXTNAME = `name`) of a multi-HDU file, e.g. the effective
// PSF ("PSF") or the noise correlation kernel ("NOISE_CORR") stored beside a reconstruction.
struct FitsExtension {
  std::string name;    // EXTNAME: 1..68 printable ASCII characters without quotes, unique in the file
  ImageStack planes;   // one plane: a 2-D image (NAXIS = 2); more: a cube (NAXIS = 3)
  FitsHeader header;   // its own user keywords (EXTNAME is written from `name`; a different one is refused)
  FitsType type = FitsType::kFloat32;
};

// Writes a primary 2-D image followed by the image extensions in order, as one atomic write (the file
// appears complete or not at all). ReadFits of the result reads the primary image as before. Extension names
// are unique ignoring case (how EXTNAME is matched). InvalidArgument naming the extension for an empty or
// duplicate name, empty planes, planes of different shapes, an EXTNAME keyword in its header that differs
// from its name, or (kFloat32) values beyond float32's range.
void WriteFitsWithExtensions(const std::string& path, const Image& primary, const FitsHeader& header,
                             const std::vector<FitsExtension>& extensions, FitsType type = FitsType::kFloat32);

// The same with a primary cube (NAXIS = 3 for more than one plane): e.g. a movie with its times in an extension.
void WriteFitsCubeWithExtensions(const std::string& path, const ImageStack& primary, const FitsHeader& header,
                                 const std::vector<FitsExtension>& extensions, FitsType type = FitsType::kFloat32);

// A 2-D image written by rows, for an image that is never held whole (a tiled reconstruction of a whole
// detector, solvers/tiling.hpp). The primary HDU is created with its full shape in a temporary file beside
// `path` (as AtomicWrite names it); rows are written in any order (rows never written read as 0); Finish adds
// the header's keywords (a reconstruction's are known only at the end; space for them is reserved up front, so
// the pixels are not moved), then the extensions, and renames the file onto `path`: it appears complete or not
// at all. Destroyed without Finish (an error, a cancelled run), it removes the temporary file.
// IoError naming `path` for a missing folder or a failed write; InvalidArgument as WriteFits for values.
class FitsRowWriter {
 public:
  FitsRowWriter(const std::string& path, Shape shape, FitsType type = FitsType::kFloat32);
  ~FitsRowWriter();
  FitsRowWriter(const FitsRowWriter&) = delete;
  FitsRowWriter& operator=(const FitsRowWriter&) = delete;

  // Rows [row0, row0 + rows.rows()) of the image; rows.cols() must be the image's width.
  void WriteRows(Index row0, const Image& rows);
  // Ends the file (see above). Extensions follow WriteFitsWithExtensions's rules.
  void Finish(const FitsHeader& header, const std::vector<FitsExtension>& extensions = {});

 private:
  std::string path_, tmp_;
  Shape shape_;
  FitsType type_;
  void* file_ = nullptr;  // fitsfile*
};

// A cube written plane by plane, for planes that are never held together (a movie: solvers/video_stream.hpp;
// holding them costs memory and, on a fresh page, a page fault per 4 KB). The rules of FitsRowWriter: a temporary
// file beside `path`, header space reserved up front, Finish writes the header's keywords and the extensions
// and renames the file onto `path`; destroyed without Finish, it removes the temporary file. `reserve_planes`
// (>= 0) sizes the cube at the start (NAXIS3), grown when more planes come and cut to the planes written at
// Finish; one plane is written as a 2-D image (NAXIS = 2), as WriteFitsCubeWithExtensions does.
// IoError naming `path` for a missing folder or a failed write; InvalidArgument for a plane of another shape, a
// value beyond float32's range (kFloat32), Finish with no plane, or use after Finish.
class FitsCubeWriter {
 public:
  FitsCubeWriter(const std::string& path, Shape plane, Index reserve_planes = 0, FitsType type = FitsType::kFloat32);
  ~FitsCubeWriter();
  FitsCubeWriter(const FitsCubeWriter&) = delete;
  FitsCubeWriter& operator=(const FitsCubeWriter&) = delete;

  // Writes `plane` as plane planes() (0-based) of the cube.
  void Append(const Image& plane);
  Index planes() const { return planes_; }
  // Ends the file (see above). Extensions follow WriteFitsWithExtensions's rules.
  void Finish(const FitsHeader& header, const std::vector<FitsExtension>& extensions = {});

 private:
  void Resize(Index planes, int naxis);
  std::string path_, tmp_;
  Shape plane_;
  FitsType type_;
  Index planes_ = 0, capacity_ = 0;
  std::vector<float> buffer_;  // the float32 conversion of a plane, reused
  void* file_ = nullptr;       // fitsfile*
};

// Reads the image extension whose EXTNAME is `name` (case-insensitive, as cfitsio matches it); its header
// includes EXTNAME. IoError naming the path and the names the file has when none matches, or for the
// reasons of ReadFits (no data, NAXIS other than 2 or 3, truncated).
FitsData ReadFitsExtension(const std::string& path, const std::string& name);

// The EXTNAMEs of the file's extensions, in order (HDUs without one are skipped). IoError as ReadFits.
std::vector<std::string> FitsExtensionNames(const std::string& path);

// Reads the primary HDU, or if it has no data the first image extension that has (e.g. a
// tile-compressed .fits.fz, or a file whose primary HDU only carries a header).
// IoError naming `path` for: a missing/unreadable file, a file that is not FITS or is truncated,
// no image data, NAXIS other than 2 or 3 (NAXIS = 3 with NAXIS3 = 1 is one plane).
FitsData ReadFits(const std::string& path);

// ReadFits that requires exactly one plane; IoError naming the path and the cube's shape otherwise.
Image ReadFitsImage(const std::string& path);

// The header and the shape (planes x rows x cols) of the image ReadFits would read, without its pixels.
struct FitsImageInfo {
  FitsHeader header;
  Index planes = 0, rows = 0, cols = 0;
};
FitsImageInfo ReadFitsInfo(const std::string& path);

// Rows [y0, y0 + rows) x columns [x0, x0 + cols) of every plane of the image ReadFits would read, as ReadFits
// converts them (fits_read_subset: only that section is read from the file), and the header. A tile's window of
// a detector too large to hold, or a job that solves one tile (solvers/tiling.hpp). InvalidArgument for a
// section outside the image; IoError as ReadFits.
FitsData ReadFitsSection(const std::string& path, Index y0, Index x0, Index rows, Index cols);

}  // namespace aosr
