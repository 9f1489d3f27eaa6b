#!/usr/bin/python3
"""Sky coordinates of aosr's FITS files as astropy reads them (ctest cli.wcs_astropy, label physics).

Runs `aosr simulate` on a one-star scene whose frame 0 carries a DM image shift, then `aosr reconstruct`
(tikhonov, drizzle), and checks with astropy.wcs (wcslib), independently of aosr's own WCS code, that
  * every sky image carries a celestial TAN WCS and BUNIT; the PSF kernels carry none;
  * the truth and the reconstructions share the HR grid's WCS, with the scene's pointing at the grid's centre,
    pitch = the manifest's hr_mas and the +y axis at the scene's position angle east of north;
  * the star's sky position through frame 0's WCS at the position where frame 0 shows it (a windowed centroid
    of the noiseless expected frame) is its position through the HR WCS at its truth position, to 0.02 HR px;
  * the reconstruction shows the star where the HR WCS says it is (0.05 HR px: the estimate's own centroid).
Usage: wcs_astropy_check.py [path/to/aosr]  (default: build/aosr of the source tree). Exit 77 (ctest: skipped)
when astropy or numpy cannot be imported.
"""
import json
import os
import subprocess
import sys
import tempfile

try:
    import numpy as np
    from astropy.io import fits
    from astropy.wcs import WCS
    from astropy.coordinates import SkyCoord
    import astropy.units as u
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"SKIPPED: astropy/numpy not importable ({e}); install python3-astropy python3-numpy (scripts/setup.sh)")
    sys.exit(77)

HERE = os.path.dirname(os.path.abspath(__file__))
AOSR = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "..", "..", "build", "aosr")

RA, DEC, PA = 150.1, -30.2, 25.0
SHIFT0 = [0.37, -0.21]  # frame 0's DM image shift, camera px (y, x)
SCENE = {
    "name": "wcs-astropy",
    "telescope": {
        "name": "wcs-test",
        "telescope": {"diameter_m": 8.0, "obstruction": 0.0, "pupil_px": 128},
        "science": {"wavelength_m": 2.2e-6, "camera_pixel_lambda_over_d": 0.25},
    },
    "frames": 4,
    "r": 2,
    "psf": {"window_lambda_over_d": 8},
    "ao": {"mode": "none"},
    "offsets": {"type": "design", "frames": [{"shift_px": SHIFT0}, {"shift_px": [0.0, 0.5]},
                                             {"shift_px": [0.5, 0.0]}, {"shift_px": [0.5, 0.5]}]},
    "sky": {"ra_deg": RA, "dec_deg": DEC, "position_angle_deg": PA},
    "detector": {"frame_px": 48, "noise": "none", "saturation": False},
    "objects": [{"type": "stars", "catalogue": [{"y_px": 20.3, "x_px": 27.6, "flux_e": 1e5}]}],
}

failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def run(*args):
    subprocess.run([AOSR, *args, "--threads", "1"], check=True, stdout=subprocess.DEVNULL)


def windowed_centroid(img, y0, x0, sigma):
    """Gaussian-windowed centroid iterated to its fixed point (the centre of a symmetric, sampled image)."""
    yy, xx = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    y, x = y0, x0
    for _ in range(200):
        w = np.exp(-((yy - y) ** 2 + (xx - x) ** 2) / (2 * sigma ** 2)) * img
        ny, nx = (w * yy).sum() / w.sum(), (w * xx).sum() / w.sum()
        done = abs(ny - y) + abs(nx - x) < 1e-12
        y, x = ny, nx
        if done:
            break
    return y, x


def sky(wcs, y, x):
    """aosr pixel (y, x), 0-based, is astropy's pixel (x, y) with origin 0."""
    ra, dec = wcs.all_pix2world([[x, y]], 0)[0]
    return SkyCoord(ra * u.deg, dec * u.deg, frame="icrs")


with tempfile.TemporaryDirectory(prefix="aosr_wcs_astropy_") as tmp:
    scene = os.path.join(tmp, "scene.json")
    with open(scene, "w") as f:
        json.dump(SCENE, f)
    sim = os.path.join(tmp, "sim")
    run("simulate", scene, "-o", sim)
    run("reconstruct", sim, "-m", "tikhonov", "--lambda", "1e-4", "-o", os.path.join(sim, "tik.fits"))
    run("reconstruct", sim, "-m", "drizzle", "-o", os.path.join(sim, "dz.fits"))
    manifest = json.load(open(os.path.join(sim, "manifest.json")))
    r = manifest["r"]
    hr_mas = manifest["pixel_scale"]["hr_mas"]

    headers = {n: fits.getheader(os.path.join(sim, n)) for n in
               ["frames.fits", "valid.fits", "weights.fits", "expected.fits", "truth.fits", "psfs.fits",
                "tik.fits", "dz.fits", "dz_weight.fits"]}
    for name, h in headers.items():
        if name == "psfs.fits":
            check("CTYPE1" not in h, f"{name}: no WCS (PSF kernels are not sky images)")
            continue
        w = WCS(h, naxis=2)
        check(list(w.wcs.ctype) == ["RA---TAN", "DEC--TAN"], f"{name}: celestial TAN WCS {list(w.wcs.ctype)}")
        check(w.wcs.radesys == "ICRS", f"{name}: RADESYS {w.wcs.radesys}")
        if name not in ("valid.fits", "dz_weight.fits"):
            check(h.get("BUNIT") in ("adu", "adu-2", "electron"), f"{name}: BUNIT = {h.get('BUNIT')}")

    hr = WCS(headers["truth.fits"], naxis=2)
    lr = WCS(headers["frames.fits"], naxis=2)
    rows, cols = fits.getdata(os.path.join(sim, "truth.fits")).shape
    centre = sky(hr, (rows - 1) / 2, (cols - 1) / 2)
    check(centre.separation(SkyCoord(RA * u.deg, DEC * u.deg)).to(u.mas).value < 1e-6,
          f"the pointing ({RA}, {DEC}) is at the HR grid's centre")
    scale = np.sqrt(np.abs(np.linalg.det(hr.pixel_scale_matrix))) * 3.6e6
    check(abs(scale / hr_mas - 1) < 1e-9, f"HR pixel {scale:.6f} mas = manifest hr_mas {hr_mas:.6f}")
    lr_scale = np.sqrt(np.abs(np.linalg.det(lr.pixel_scale_matrix))) * 3.6e6
    check(abs(lr_scale / (r * hr_mas) - 1) < 1e-9, f"camera pixel {lr_scale:.6f} mas = r x HR pixel")
    # Position angle of the +y axis, east of north, at the centre.
    up = sky(hr, (rows - 1) / 2 + 100, (cols - 1) / 2)
    pa = centre.position_angle(up).to(u.deg).value
    check(abs(pa - PA) < 1e-3, f"+y axis at position angle {pa:.5f} deg (scene: {PA})")
    for name in ["tik.fits", "dz.fits", "dz_weight.fits"]:
        w = WCS(headers[name], naxis=2)
        corners = [(0, 0), (rows - 1, cols - 1), (0, cols - 1)]
        worst = max(sky(w, y, x).separation(sky(hr, y, x)).to(u.mas).value for y, x in corners) / hr_mas
        check(worst < 1e-6, f"{name}: the truth's HR WCS (corners agree to {worst:.1e} HR px)")

    star = manifest["stars"][0]
    star_sky = sky(hr, star["y_hr_px"], star["x_hr_px"])
    expected = fits.getdata(os.path.join(sim, "expected.fits"))
    guess = (star["y_px"], star["x_px"])
    y0, x0 = windowed_centroid(expected[0], *guess, 2.5)
    miss = sky(lr, y0, x0).separation(star_sky).to(u.mas).value / hr_mas
    check(miss < 0.02, f"frame 0 shows the star at LR ({y0:.4f}, {x0:.4f}): {miss:.5f} HR px from its HR-WCS position")
    moved = np.hypot(y0 - guess[0] - SHIFT0[0], x0 - guess[1] - SHIFT0[1])
    check(moved < 0.01, f"frame 0's image is displaced by its DM shift {SHIFT0} (residual {moved:.5f} LR px)")

    for name in ["tik.fits", "dz.fits"]:
        img = fits.getdata(os.path.join(sim, name)).astype(float)
        yr, xr = windowed_centroid(img, star["y_hr_px"], star["x_hr_px"], 5.0)
        miss = sky(WCS(headers[name], naxis=2), yr, xr).separation(star_sky).to(u.mas).value / hr_mas
        check(miss < 0.05, f"{name} shows the star at HR ({yr:.4f}, {xr:.4f}), {miss:.5f} HR px from its HR-WCS position")

if failures:
    print(f"{len(failures)} check(s) failed")
    sys.exit(1)
print("all checks passed")
