#include "aosr/io/wcs.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <tuple>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

constexpr double kDegPerRad = 180.0 / M_PI;
constexpr double kRadPerDeg = M_PI / 180.0;

// The native longitude of the celestial pole, φ_p = LONPOLE, at its default for a zenithal projection
// (θ0 = 90°): 180° unless the reference point is the north pole itself ([II] §2.4).
double DefaultLonpoleDeg(double dec0_deg) { return dec0_deg >= 90.0 ? 0.0 : 180.0; }

double Determinant(const Wcs& w) { return w.cd[0][0] * w.cd[1][1] - w.cd[0][1] * w.cd[1][0]; }

double NormaliseRa(double ra_deg) {
  double a = std::fmod(ra_deg, 360.0);
  if (a < 0) a += 360.0;
  return a >= 360.0 ? 0.0 : a;  // fmod of a tiny negative number can round to 360
}

std::string Trimmed(std::string s) {
  while (!s.empty() && s.back() == ' ') s.pop_back();
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

void CheckWcs(const char* fn, const Wcs& w) {
  for (int i = 0; i < 2; ++i) {
    const std::string n = std::to_string(i + 1);
    CheckArgument(std::isfinite(w.crpix[i]), fn, "CRPIX" + n, w.crpix[i], "a finite pixel coordinate");
    CheckArgument(std::isfinite(w.crval[i]), fn, "CRVAL" + n, w.crval[i], "a finite angle in degrees");
    for (int j = 0; j < 2; ++j)
      CheckArgument(std::isfinite(w.cd[i][j]), fn, "CD" + n + "_" + std::to_string(j + 1), w.cd[i][j],
                    "a finite number of degrees per pixel");
  }
  CheckArgument(std::abs(w.crval[1]) <= 90.0, fn, "CRVAL2", w.crval[1], "a declination in [-90, 90] deg");
  const double det = Determinant(w);
  CheckArgument(std::isfinite(det) && det != 0.0, fn, "CD matrix determinant", det,
                "an invertible matrix (non-zero determinant)");
  if (w.equinox) CheckArgument(std::isfinite(*w.equinox), fn, "EQUINOX", *w.equinox, "a finite year");
  CheckArgument(w.radesys.find('\'') == std::string::npos, fn, "RADESYS", w.radesys, "a name such as ICRS or FK5");
}

// ---- Header reading --------------------------------------------------------------------------------------

constexpr const char* kWcsFn = "WcsFromHeader";

double Number(const FitsHeader& h, const std::string& name) {
  const FitsKeyword* k = h.Find(name);
  if (k == nullptr) throw InvalidArgument(kWcsFn, name, "(missing)", "a real number");
  double v = 0;
  if (const double* d = std::get_if<double>(&k->value)) {
    v = *d;
  } else if (const long long* i = std::get_if<long long>(&k->value)) {
    v = double(*i);
  } else {
    const std::string* s = std::get_if<std::string>(&k->value);
    throw InvalidArgument(kWcsFn, name, s ? "'" + *s + "'" : std::string("a logical"), "a real number");
  }
  CheckArgument(std::isfinite(v), kWcsFn, name, v, "a finite real number");
  return v;
}

double NumberOr(const FitsHeader& h, const std::string& name, double fallback) {
  return h.Has(name) ? Number(h, name) : fallback;
}

std::string Text(const FitsHeader& h, const std::string& name) {
  const FitsKeyword* k = h.Find(name);
  if (k == nullptr) throw InvalidArgument(kWcsFn, name, "(missing)", "a string");
  const std::string* s = std::get_if<std::string>(&k->value);
  if (s == nullptr) throw InvalidArgument(kWcsFn, name, "(not a string)", "a string");
  return Trimmed(*s);
}

// Distortions and projection variants this module does not apply: refused by name.
void RefuseDistortions(const FitsHeader& h) {
  for (const char* k : {"A_ORDER", "B_ORDER", "AP_ORDER", "BP_ORDER"})
    if (h.Has(k))
      throw InvalidArgument(kWcsFn, k, "(present)",
                            "no SIP distortion: aosr's WCS is the plain TAN projection (SIP is not supported)");
  for (const FitsKeyword& k : h.keywords()) {
    const std::string& n = k.name;
    const bool pv = n.size() > 4 && (n.compare(0, 4, "PV1_") == 0 || n.compare(0, 4, "PV2_") == 0);
    const bool table = n.compare(0, 5, "CPDIS") == 0 || n.compare(0, 5, "CQDIS") == 0 ||
                       n.compare(0, 6, "D2IMDIS") == 0 || n == "DP1" || n == "DP2" || n == "DQ1" || n == "DQ2";
    if (pv)
      throw InvalidArgument(kWcsFn, n, "(present)",
                            "no projection parameters: TAN takes none, and the TPV distortion they encode is not "
                            "supported");
    if (table) throw InvalidArgument(kWcsFn, n, "(present)", "no distortion tables (not supported)");
  }
}

}  // namespace

double Wcs::PixelScaleDeg(int axis) const {
  CheckArgument(axis == 0 || axis == 1, "Wcs::PixelScaleDeg", "axis", axis, "0 (x) or 1 (y)");
  return std::hypot(cd[0][axis], cd[1][axis]);
}

Wcs TangentPlaneWcs(double ra_deg, double dec_deg, double pixel_rad, double position_angle_deg,
                    PixelCoord reference) {
  const char* fn = "TangentPlaneWcs";
  CheckArgument(std::isfinite(ra_deg), fn, "ra_deg", ra_deg, "a finite angle");
  CheckArgument(std::isfinite(dec_deg) && std::abs(dec_deg) <= 90.0, fn, "dec_deg", dec_deg, "[-90, 90]");
  CheckArgument(std::isfinite(pixel_rad) && pixel_rad > 0, fn, "pixel_rad", pixel_rad, "> 0");
  CheckArgument(std::isfinite(position_angle_deg), fn, "position_angle_deg", position_angle_deg, "a finite angle");
  CheckArgument(std::isfinite(reference.y) && std::isfinite(reference.x), fn, "reference",
                ToString(reference.y) + ", " + ToString(reference.x), "a finite pixel position");
  Wcs w;
  w.crpix[0] = reference.x + 1.0;
  w.crpix[1] = reference.y + 1.0;
  w.crval[0] = NormaliseRa(ra_deg);
  w.crval[1] = dec_deg;
  // +y points to position angle PA (east of north): (ξ, η) ∝ (sin PA, cos PA); +x is +y turned by −90° on
  // the sky as seen (east to the left of north): (−cos PA, sin PA). Determinant −s² (the sky's parity).
  const double s = pixel_rad * kDegPerRad, pa = position_angle_deg * kRadPerDeg;
  w.cd[0][0] = -s * std::cos(pa);
  w.cd[0][1] = s * std::sin(pa);
  w.cd[1][0] = s * std::sin(pa);
  w.cd[1][1] = s * std::cos(pa);
  return w;
}

// φ_p is 0° or 180° (DefaultLonpoleDeg), so cos φ_p = ±1 and sin φ_p = 0 exactly: sin(φ − φ_p) = c sin φ and
// cos(φ − φ_p) = c cos φ with c = cos φ_p. The formulas below are [II]'s with that substitution and with the
// TAN native coordinates written through (ξ, η) directly (sin θ = k, cos θ sin φ = ξ k, cos θ cos φ = −η k,
// k = 1/√(1 + R²), ξ, η in radians), which avoids asin near ±1 and keeps full precision at small offsets.
SkyCoord PixelToSky(const Wcs& w, PixelCoord pixel) {
  CheckWcs("PixelToSky", w);
  CheckArgument(std::isfinite(pixel.y) && std::isfinite(pixel.x), "PixelToSky", "pixel",
                ToString(pixel.y) + ", " + ToString(pixel.x), "a finite position");
  // 1-2: p − CRPIX with p = (x + 1, y + 1), then (ξ, η) = CD · q, degrees -> radians.
  const double q1 = pixel.x + 1.0 - w.crpix[0], q2 = pixel.y + 1.0 - w.crpix[1];
  const double xi = (w.cd[0][0] * q1 + w.cd[0][1] * q2) * kRadPerDeg;
  const double eta = (w.cd[1][0] * q1 + w.cd[1][1] * q2) * kRadPerDeg;
  // 3-4: [II] eq. 2 times 1/k (a common positive factor of all three terms, which atan2 ignores):
  //   a = cos δ cos(α − α_p) / k = cos δ_p + c η sin δ_p (c = cos φ_p),  b = cos δ sin(α − α_p) / k = −c ξ,  s = sin δ / k = sin δ_p − c η cos δ_p.
  const double dec_p = w.crval[1] * kRadPerDeg;
  const double c = DefaultLonpoleDeg(w.crval[1]) == 0.0 ? 1.0 : -1.0;
  const double a = std::cos(dec_p) + c * eta * std::sin(dec_p);
  const double b = -c * xi;
  const double s = std::sin(dec_p) - c * eta * std::cos(dec_p);
  SkyCoord sky;
  sky.ra_deg = NormaliseRa(w.crval[0] + std::atan2(b, a) * kDegPerRad);
  sky.dec_deg = std::atan2(s, std::hypot(a, b)) * kDegPerRad;
  return sky;
}

PixelCoord SkyToPixel(const Wcs& w, SkyCoord sky) {
  const char* fn = "SkyToPixel";
  CheckWcs(fn, w);
  CheckArgument(std::isfinite(sky.ra_deg), fn, "sky.ra_deg", sky.ra_deg, "a finite angle");
  CheckArgument(std::isfinite(sky.dec_deg) && std::abs(sky.dec_deg) <= 90.0, fn, "sky.dec_deg", sky.dec_deg,
                "[-90, 90]");
  // [II] eq. 5 (celestial -> native), with the differences taken in degrees first and the near-cancelling
  // terms rewritten (1 − cos Δα = 2 sin²(Δα/2)) so that small offsets keep their precision:
  //   sin θ = cos(δ − δ_p) − 2 cos δ cos δ_p sin²(Δα/2)
  //   cos θ cos(φ − φ_p) = sin(δ − δ_p) + 2 cos δ sin δ_p sin²(Δα/2)
  //   cos θ sin(φ − φ_p) = −cos δ sin Δα.
  double dra = std::fmod(sky.ra_deg - w.crval[0], 360.0);
  if (dra > 180.0) dra -= 360.0;
  if (dra < -180.0) dra += 360.0;
  const double da = dra * kRadPerDeg, ddec = (sky.dec_deg - w.crval[1]) * kRadPerDeg;
  const double dec = sky.dec_deg * kRadPerDeg, dec_p = w.crval[1] * kRadPerDeg;
  const double hav = 2.0 * std::pow(std::sin(da / 2), 2);
  const double sin_theta = std::cos(ddec) - std::cos(dec) * std::cos(dec_p) * hav;
  const double cos_dphi = std::sin(ddec) + std::cos(dec) * std::sin(dec_p) * hav;
  const double sin_dphi = -std::cos(dec) * std::sin(da);
  CheckArgument(sin_theta > 1e-12, fn, "sky",
                ToString(sky.ra_deg) + ", " + ToString(sky.dec_deg) + " deg",
                "a position less than 90 deg from the reference point (CRVAL) the TAN projection is centred on");
  // TAN: ξ = R_θ sin φ, η = −R_θ cos φ with R_θ = cot θ (radians); cos θ sin φ = c·(cos θ sin(φ − φ_p)) etc.
  const double c = DefaultLonpoleDeg(w.crval[1]) == 0.0 ? 1.0 : -1.0;
  const double xi = c * sin_dphi / sin_theta * kDegPerRad;
  const double eta = -c * cos_dphi / sin_theta * kDegPerRad;
  // q = CD⁻¹ (ξ, η).
  const double det = Determinant(w);
  const double q1 = (w.cd[1][1] * xi - w.cd[0][1] * eta) / det;
  const double q2 = (-w.cd[1][0] * xi + w.cd[0][0] * eta) / det;
  return {q2 + w.crpix[1] - 1.0, q1 + w.crpix[0] - 1.0};
}

double AngularSeparationDeg(SkyCoord a, SkyCoord b) {
  const double d1 = a.dec_deg * kRadPerDeg, d2 = b.dec_deg * kRadPerDeg;
  const double dra = (b.ra_deg - a.ra_deg) * kRadPerDeg;
  const double h = std::pow(std::sin((d2 - d1) / 2), 2) + std::cos(d1) * std::cos(d2) * std::pow(std::sin(dra / 2), 2);
  return 2.0 * std::asin(std::min(1.0, std::sqrt(h))) * kDegPerRad;
}

bool HasWcs(const FitsHeader& header) { return header.Has("CTYPE1") || header.Has("CTYPE2"); }

Wcs WcsFromHeader(const FitsHeader& h) {
  // Axis types: celestial TAN, RA first.
  const std::string c1 = Text(h, "CTYPE1");
  const std::string c2 = Text(h, "CTYPE2");
  for (const auto& [name, value, expected] :
       {std::tuple{"CTYPE1", c1, "RA---TAN"}, std::tuple{"CTYPE2", c2, "DEC--TAN"}}) {
    if (value == expected) continue;
    const std::string v = "'" + value + "'";
    if (value.size() > 8 && value.compare(0, 8, expected) == 0)
      throw InvalidArgument(kWcsFn, name, v,
                            std::string("'") + expected + "' without a distortion suffix (" + value.substr(8) +
                                " is not supported)");
    if (value.size() == 8 && value.compare(0, 4, std::string(expected).substr(0, 4)) == 0)
      throw InvalidArgument(kWcsFn, name, v,
                            std::string("'") + expected + "': only the gnomonic TAN projection is supported, not " +
                                value.substr(5));
    throw InvalidArgument(kWcsFn, name, v,
                          std::string("'") + expected + "' (celestial RA/Dec axes in this order, TAN projection)");
  }
  RefuseDistortions(h);
  for (const char* k : {"CUNIT1", "CUNIT2"})
    if (h.Has(k) && Text(h, k) != "DEG") throw InvalidArgument(kWcsFn, k, "'" + Text(h, k) + "'", "'deg'");

  Wcs w;
  w.crpix[0] = Number(h, "CRPIX1");
  w.crpix[1] = Number(h, "CRPIX2");
  w.crval[0] = Number(h, "CRVAL1");
  w.crval[1] = Number(h, "CRVAL2");
  CheckArgument(std::abs(w.crval[1]) <= 90.0, kWcsFn, "CRVAL2", w.crval[1], "a declination in [-90, 90] deg");
  w.crval[0] = NormaliseRa(w.crval[0]);

  // The linear part, in one of the three forms of [I] §2.1.2.
  const char* kCd[2][2] = {{"CD1_1", "CD1_2"}, {"CD2_1", "CD2_2"}};
  const char* kPc[2][2] = {{"PC1_1", "PC1_2"}, {"PC2_1", "PC2_2"}};
  bool has_cd = false, has_pc = false;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) has_cd = has_cd || h.Has(kCd[i][j]), has_pc = has_pc || h.Has(kPc[i][j]);
  const bool has_crota = h.Has("CROTA2");
  if (h.Has("CROTA1") && Number(h, "CROTA1") != NumberOr(h, "CROTA2", 0.0))
    throw InvalidArgument(kWcsFn, "CROTA1", ToString(Number(h, "CROTA1")),
                          "absent, or equal to CROTA2 (the rotation of the celestial axes is CROTA2)");
  if (has_cd) {
    if (has_pc)
      throw InvalidArgument(kWcsFn, "PCi_j", "(given with CDi_j)",
                            "either a CDi_j matrix or PCi_j with CDELTi, not both (Greisen & Calabretta 2002)");
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j) w.cd[i][j] = NumberOr(h, kCd[i][j], 0.0);  // CDELTi and CROTA2 ignored
  } else {
    if (!h.Has("CDELT1") || !h.Has("CDELT2"))
      throw InvalidArgument(kWcsFn, h.Has("CDELT1") ? "CDELT2" : "CDELT1", "(missing)",
                            "the pixel scale: a CDi_j matrix, or CDELT1 and CDELT2 (with PCi_j or CROTA2)");
    const double cdelt[2] = {Number(h, "CDELT1"), Number(h, "CDELT2")};
    if (has_pc) {
      if (has_crota)
        throw InvalidArgument(kWcsFn, "CROTA2", "(given with PCi_j)",
                              "either PCi_j or CROTA2, not both (Greisen & Calabretta 2002)");
      for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) w.cd[i][j] = cdelt[i] * NumberOr(h, kPc[i][j], i == j ? 1.0 : 0.0);
    } else {
      // [II] eq. 189: the rotation ρ = CROTA2 of the celestial axes.
      const double rho = NumberOr(h, "CROTA2", 0.0) * kRadPerDeg;
      w.cd[0][0] = cdelt[0] * std::cos(rho);
      w.cd[0][1] = -cdelt[1] * std::sin(rho);
      w.cd[1][0] = cdelt[0] * std::sin(rho);
      w.cd[1][1] = cdelt[1] * std::cos(rho);
    }
  }
  const double det = Determinant(w);
  CheckArgument(std::isfinite(det) && det != 0.0, kWcsFn, has_cd ? "CDi_j" : (has_pc ? "PCi_j, CDELTi" : "CDELTi"),
                "a matrix of determinant " + ToString(det), "an invertible pixel-to-sky matrix");
  if (h.Has("LONPOLE")) {
    const double lonpole = Number(h, "LONPOLE"), expected = DefaultLonpoleDeg(w.crval[1]);
    if (std::abs(lonpole - expected) > 1e-9)
      throw InvalidArgument(kWcsFn, "LONPOLE", ToString(lonpole),
                            ToString(expected) + " (its default for this CRVAL2; other values are not supported)");
  }
  w.radesys = h.Has("RADESYS") ? Text(h, "RADESYS") : h.Has("RADECSYS") ? Text(h, "RADECSYS") : std::string();
  if (h.Has("EQUINOX")) {
    w.equinox = Number(h, "EQUINOX");
  } else if (h.Has("EPOCH")) {
    w.equinox = Number(h, "EPOCH");
  }
  return w;
}

void WriteWcs(const Wcs& w, FitsHeader* header) {
  const char* fn = "WriteWcs";
  CheckArgument(header != nullptr, fn, "header", "null", "a header to write into");
  CheckWcs(fn, w);
  for (const char* k : {"PC1_1", "PC1_2", "PC2_1", "PC2_2", "CDELT1", "CDELT2", "CROTA1", "CROTA2"})
    CheckArgument(!header->Has(k), fn, "header", std::string(k) + " present",
                  "a header without another WCS's PCi_j/CDELTi/CROTAi (they would contradict the CD matrix)");
  FitsHeader& h = *header;
  h.Set("WCSAXES", 2, "number of world coordinate axes");
  h.Set("CTYPE1", "RA---TAN", "right ascension, gnomonic projection");
  h.Set("CTYPE2", "DEC--TAN", "declination, gnomonic projection");
  h.Set("CUNIT1", "deg", "unit of CRVAL1 and CD1_j");
  h.Set("CUNIT2", "deg", "unit of CRVAL2 and CD2_j");
  h.Set("CRPIX1", w.crpix[0], "reference pixel x (1-based; aosr column x is FITS x + 1)");
  h.Set("CRPIX2", w.crpix[1], "reference pixel y (1-based; aosr row y is FITS y + 1)");
  h.Set("CRVAL1", w.crval[0], "[deg] RA at the reference pixel");
  h.Set("CRVAL2", w.crval[1], "[deg] Dec at the reference pixel");
  h.Set("CD1_1", w.cd[0][0], "[deg/px] d(xi)/dx");
  h.Set("CD1_2", w.cd[0][1], "[deg/px] d(xi)/dy");
  h.Set("CD2_1", w.cd[1][0], "[deg/px] d(eta)/dx");
  h.Set("CD2_2", w.cd[1][1], "[deg/px] d(eta)/dy");
  h.Set("LONPOLE", DefaultLonpoleDeg(w.crval[1]), "[deg] native longitude of the celestial pole");
  if (!w.radesys.empty()) h.Set("RADESYS", w.radesys, "celestial reference system");
  if (w.equinox) h.Set("EQUINOX", *w.equinox, "[yr] equinox of the reference system");
}

void SetImageKeywords(const std::optional<Wcs>& wcs, const std::string& bunit, FitsHeader* header) {
  CheckArgument(header != nullptr, "SetImageKeywords", "header", "null", "a header to write into");
  if (!bunit.empty()) header->Set("BUNIT", bunit, "unit of the data values");
  if (wcs) WriteWcs(*wcs, header);
}

Wcs HrWcs(const Wcs& lr, int r, double offset_y_hr, double offset_x_hr) {
  CheckArgument(r >= 1, "HrWcs", "r", r, ">= 1");
  CheckArgument(std::isfinite(offset_y_hr) && std::isfinite(offset_x_hr), "HrWcs", "offset",
                ToString(offset_y_hr) + ", " + ToString(offset_x_hr), "finite HR pixels");
  Wcs hr = lr;
  const double offset[2] = {offset_x_hr, offset_y_hr};  // FITS axis order: x, y
  for (int i = 0; i < 2; ++i) {
    hr.crpix[i] = (lr.crpix[i] - 0.5) * r + 0.5 - offset[i];
    for (int j = 0; j < 2; ++j) hr.cd[i][j] = lr.cd[i][j] / r;
  }
  return hr;
}

Wcs LrWcs(const Wcs& hr, int r, double offset_y_hr, double offset_x_hr) {
  CheckArgument(r >= 1, "LrWcs", "r", r, ">= 1");
  CheckArgument(std::isfinite(offset_y_hr) && std::isfinite(offset_x_hr), "LrWcs", "offset",
                ToString(offset_y_hr) + ", " + ToString(offset_x_hr), "finite HR pixels");
  Wcs lr = hr;
  const double offset[2] = {offset_x_hr, offset_y_hr};
  for (int i = 0; i < 2; ++i) {
    lr.crpix[i] = (hr.crpix[i] + offset[i] - 0.5) / r + 0.5;
    for (int j = 0; j < 2; ++j) lr.cd[i][j] = hr.cd[i][j] * r;
  }
  return lr;
}

}  // namespace aosr
