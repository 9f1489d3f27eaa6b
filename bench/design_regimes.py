#!/usr/bin/python3
"""Where a designed phase beats the classic raster (issue 25): bench/results/design_regimes.md.

For each cell (science band / camera pixel in lambda/D, r, N) of the paper's 8 m system (analytic AO, the K-band
camera's 56.7 mas pixel, or 3.74 lambda/D as on the paper's bench):
  1. `aosr design` with tip/tilt and 20-mode Zernike offsets (objective A, 1 realisation x 2 screens for the
     optimiser, 3 fresh realisations for the gain and its standard error): the expected gain over the raster.
  2. held-out reconstructions: USAF and the demo truth at a fresh sky seed and fresh noise, simulated with the
     raster, with the best design, and with the raster moved by half an HR pixel (1/(2r) camera px in y and x:
     the mechanism's prediction, below), reconstructed with Tikhonov (GCV) and TV (60 iterations), PSNR by
     `aosr evaluate` with a 4-camera-pixel border left out.

Usage (from the repository root, after building build/aosr):
    bench/design_regimes.py [--quick] [--out bench/results/design_regimes.md]
--quick: K and J band at r = 2 only, with one fine-sky, one noise and one objective-B row (a smoke run, ~1 min).
--bands: print the error-band tables from an earlier full run's files (build/regimes) and stop.
Two jobs at a time (the machine has 2 cores).
"""
import argparse
import concurrent.futures as cf
import json
import math
import os
import subprocess
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
AOSR = os.path.join(ROOT, "build", "aosr")
SCRATCH = os.path.join(ROOT, "build", "regimes")
PRESET = json.load(open(os.path.join(ROOT, "data", "telescopes", "paper-8m.json")))
BANDS = {"K": 2.2e-6, "H": 1.6e-6, "J": 1.25e-6}
CAMERA_PIXEL_RAD = 2.2e-6 / 8.0          # the K-band camera: lambda/D at 2.2 um (56.7 mas)


def run_json(args):
    p = subprocess.run([AOSR] + [str(a) for a in args] + ["--json"], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError("aosr %s failed (%d): %s" % (" ".join(map(str, args)), p.returncode, p.stderr[-400:]))
    return json.loads(p.stdout)


def frame_px(r):
    """Camera frame side: 64 px, 32 px at r = 8 (the quick-style reduction for the expensive cells)."""
    return 32 if r >= 8 else 64


def scene(name, band, pixel_lod, r, n, offsets, obj, seed, noise=0.01, sky=1):
    tel = json.loads(json.dumps(PRESET))
    tel["name"] = "paper-8m-" + band
    tel["science"] = {"wavelength_m": BANDS[band], "camera_pixel_lambda_over_d": pixel_lod}
    objects = {"usaf": {"type": "usaf", "fill": 0.9, "first_group": -2, "last_group": 1, "flux": {"peak_e": 1000}},
               "demo": {"type": "demo", "flux": {"peak_e": 1000}}}[obj]
    return {"name": name, "seed": seed, "telescope": tel, "frames": n, "r": r, "ao": {"mode": "analytic"},
            "offsets": offsets, "objects": [objects],
            "detector": {"frame_px": frame_px(r), "noise": "peak-fraction", "peak_noise_fraction": noise,
                         "saturation": False}, "sky_oversampling": sky}


def transfer_lines():
    """Per-frequency evidence for the mechanism: the transfer of a PSF sampled on the HR grid (pitch th lambda/D)
    is the continuous OTF aliased by the grid, H_s(f) = sum_k OTF(f + k/th) exp(-2 pi i (f + k/th) s). A PSF
    centred half an HR pixel off the samples (s = th/2 in y and x) gets the signs (-1)^(kx+ky) on the replicas,
    which cancel where they overlap: between 1/th - D/lambda and the HR Nyquist 1/(2 th), a band that exists
    only when th > lambda/(2D). Diffraction-limited OTF of the unobstructed pupil (numpy, no aosr)."""
    import numpy as np

    def otf(nu):
        nu = np.minimum(np.abs(nu), 1.0)
        return (2 / np.pi) * (np.arccos(nu) - nu * np.sqrt(1 - nu ** 2))

    out = ["| HR pixel [lambda/D] | HR Nyquist [D/lambda] | ratio at f/f_Nyq = 0, 1/6, 1/3, 1/2, 2/3, 5/6, 1 (along x) | "
           "2-D: band fraction with ratio < 0.9 / < 0.5 | 2-D mean ratio^2 |", "|---:|---:|---|---|---:|"]
    for th in (0.44, 0.5, 0.69, 0.88, 0.935):
        ny = 1 / (2 * th)
        ratios = []
        for f in np.linspace(0, ny, 7):
            h0 = sum(otf(f + k / th) for k in range(-3, 4))
            hh = sum(((-1) ** k) * otf(f + k / th) for k in range(-3, 4))
            ratios.append("%.2f" % (abs(hh) / h0 if h0 > 1e-12 else float("nan")))
        g = np.linspace(-ny, ny, 201)
        fx, fy = np.meshgrid(g, g)
        h0 = np.zeros_like(fx)
        hh = np.zeros_like(fx)
        for ky in range(-3, 4):
            for kx in range(-3, 4):
                t = otf(np.hypot(fx + kx / th, fy + ky / th))
                h0 += t
                hh += ((-1) ** (kx + ky)) * t
        vis = h0 > 1e-6
        q = np.abs(hh[vis]) / h0[vis]
        out.append("| %.3g | %.3g | %s | %.2f / %.2f | %.3f |" % (th, ny, " ".join(ratios), (q < 0.9).mean(),
                                                               (q < 0.5).mean(), (q ** 2).mean()))
    return out


def error_bands(d, method, crop):
    """Where a reconstruction's error sits in frequency: the error image (estimate - truth, border `crop` HR px
    left out, mean removed, Hann window) as power per band of max(|fx|, |fy|) / HR Nyquist: [0, 1/4), [1/4, 1/2),
    [1/2, 3/4), [3/4, 1]. Returns the MSE per HR pixel and the error power per band in MSE units."""
    import numpy as np
    from astropy.io import fits
    t = fits.getdata(os.path.join(d, "truth.fits")).astype(float)
    e = fits.getdata(os.path.join(d, method + ".fits")).astype(float)
    err = (e - t)[crop:-crop, crop:-crop]
    mse = (err ** 2).mean()
    err = err - err.mean()
    n = err.shape[0]
    w = np.hanning(n)[:, None] * np.hanning(err.shape[1])[None, :]
    p = np.abs(np.fft.fft2(err * w)) ** 2
    fy = np.abs(np.fft.fftfreq(n))[:, None] / 0.5
    fx = np.abs(np.fft.fftfreq(err.shape[1]))[None, :] / 0.5
    rho = np.maximum(fy, fx)
    edges = (0, 0.25, 0.5, 0.75, 1.01)
    return mse, [mse * p[(rho >= edges[i]) & (rho < edges[i + 1])].sum() / p.sum() for i in range(4)]


def band_tables():
    """Where the errors sit (error_bands), from the run's files: Tikhonov in J r = 2 N = 4 (discrete and 4x finer
    sky, noise 1 % and 0.1 %) and TV-400 in K 3.74 r = 4 N = 4; USAF. `--bands` prints them from build/regimes."""
    out = ["", "Where the error sits (`error_bands` in the script: error power per band of max(|fx|, |fy|) / HR "
           "Nyquist, in MSE units; USAF; `bench/design_regimes.py --bands` prints these from the run's files):", "",
           "| cell, method | noise [%] | s | config | MSE | [0, 1/4) | [1/4, 1/2) | [1/2, 3/4) | [3/4, 1] |",
           "|---|---:|---:|---|---:|---:|---:|---:|---:|"]
    rows = [(("J", 1.76, 2, 4), "", 1, s, "tikhonov", 8) for s in (1, 4)]
    rows += [(("J", 1.76, 2, 4), "-noise0.001", 0.1, s, "tikhonov", 8) for s in (1, 4)]
    rows += [(("K", 3.74, 4, 4), "-tv400", 1, s, "tv", 16) for s in (1, 4)]
    for c, tag, noise, s, m, crop in rows:
        for label in ("raster", "shifted"):
            d = os.path.join(SCRATCH, cell_key(c) + tag, label + "-usaf" + ("-s%d" % s if s > 1 else ""))
            mse, bands = error_bands(d, m, crop)
            out.append("| %s, %s | %g | %d | %s | %.0f | %s |" % (cell_key(c), "TV-400" if tag == "-tv400" else m, noise,
                                                               s, label, mse, " | ".join("%.0f" % b for b in bands)))
    return out


def cell_key(c):
    return "%s-p%.2f-r%d-N%d" % c


def design_cell(c, objective="A", noise=0.01, tag=""):
    """Objective A: tip/tilt and 20-mode Zernike (r = 8: tip/tilt only, 15 iterations: the quick-style reduction),
    Tikhonov lambda = 1e-2 (noise / 1 %)^2 (the Wiener-consistent prior: lambda scales as sigma^2). Objective B:
    tip/tilt only, 10 iterations, 2 dead-leaves training scenes, sigma = noise (scenes of peak 1)."""
    band, pixel_lod, r, n = c
    d = os.path.join(SCRATCH, cell_key(c) + tag)
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, "instrument.json")
    json.dump(scene(cell_key(c), band, pixel_lod, r, n, {"type": "raster"}, "usaf", 1, noise), open(path, "w"), indent=1)
    out = {}
    if objective == "B":
        params = ("tiptilt",)
        common = ["--objective", "B", "--starts", 1, "--iterations", 10, "--training-scenes", 2,
                  "--noise-sigma", noise, "--validation-realisations", 2]
    else:
        params = ("tiptilt",) if r >= 8 else ("tiptilt", "zernike")
        common = ["--modes", 20, "--starts", 1, "--iterations", 15 if r >= 8 else 25, "--realisations", 1,
                  "--screens", 2, "--validation-realisations", 3, "--lambda", 1e-2 * (noise / 0.01) ** 2]
    for param in params:
        t = time.time()
        j = run_json(["design", path, "--param", param, "--threads", 1, "--min-gain", 0,
                      "-o", os.path.join(d, param + ".json")] + common)
        out[param] = {"gain": j["gain"], "seconds": time.time() - t, "frames": j["design"]["frames"]}
    return (c, tag), out


def heldout(c, label, offsets, obj, noise=0.01, sky=1, tag="", tv_iterations=60):
    band, pixel_lod, r, n = c
    d = os.path.join(SCRATCH, cell_key(c) + tag, label + "-" + obj + ("-s%d" % sky if sky > 1 else ""))
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, "scene.json")
    # Fresh sky and noise: seed 777 (the designs saw seed 1's AO screens and no sky at all).
    json.dump(scene("heldout", band, pixel_lod, r, n, offsets, obj, 777, noise, sky), open(path, "w"), indent=1)
    run_json(["simulate", path, "-o", d])
    res = {}
    for m, extra in (("tikhonov", []), ("tv", ["--iterations", tv_iterations])):
        est = os.path.join(d, m + ".fits")
        run_json(["reconstruct", d, "-m", m, "-o", est] + extra)
        ev = run_json(["evaluate", "--manifest", d, "--estimate", est, "--crop", 4 * r])
        res[m] = ev["psnr_db"] if "psnr_db" in ev else ev["psnr"]
    return (cell_key(c) + tag, label, obj, sky), res


def shifted_raster(r, n):
    """The raster moved by half an HR pixel: the classic raster's shifts (for N = k^2 a k x k lattice of pitch
    1/k camera px centred on zero, as the scenes' "raster" offsets: +-1/4 for N = 4 at every r) plus 1/(2r)
    camera px in y and x."""
    k = int(round(math.sqrt(n)))
    return [{"shift_px": [((i // k) - (k - 1) / 2) / k + 0.5 / r, ((i % k) - (k - 1) / 2) / k + 0.5 / r]}
            for i in range(n)]


def best_param(g):
    return max(g, key=lambda p: g[p]["gain"]["db"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None)
    ap.add_argument("--bands", action="store_true", help="print the error-band tables from build/regimes and stop")
    a = ap.parse_args()
    if a.bands:
        print("\n".join(band_tables()))
        return 0
    t0 = time.time()
    if a.quick:
        cells = [("K", 1.0, 2, 4), ("J", 1.76, 2, 4)]
        fine = [(("J", 1.76, 2, 4), 4)]
        noise_cells, b_cells, noises = [("J", 1.76, 2, 4)], [("J", 1.76, 2, 4)], (0.1,)
    else:
        cells = [("K", 1.0, 2, 4), ("H", 1.375, 2, 4), ("J", 1.76, 2, 4),
                 ("K", 1.0, 4, 4), ("H", 1.375, 4, 4), ("J", 1.76, 4, 4),
                 ("K", 1.0, 4, 16), ("H", 1.375, 4, 16), ("J", 1.76, 4, 16),
                 ("K", 3.74, 4, 4), ("K", 3.74, 4, 16),
                 ("K", 1.0, 8, 16), ("H", 1.375, 8, 16), ("J", 1.76, 8, 16), ("K", 3.74, 8, 16)]
        # The fine-sky check (sky_oversampling): every cell where a shift or a design changed anything, the
        # K r = 2 control, at s = 4, and the two headline cells also at s = 8.
        fine = [(c, 4) for c in [("K", 1.0, 2, 4), ("H", 1.375, 2, 4), ("J", 1.76, 2, 4), ("K", 3.74, 4, 4),
                                 ("K", 3.74, 4, 16)]] + [(("J", 1.76, 2, 4), 8), (("K", 3.74, 4, 16), 8)]
        noise_cells = [("K", 1.0, 2, 4), ("J", 1.76, 2, 4)]
        b_cells = [("K", 1.0, 2, 4), ("J", 1.76, 2, 4)]
        noises = (0.001, 0.1)
    pool = cf.ThreadPoolExecutor(max_workers=2)
    dj = [pool.submit(design_cell, c) for c in cells]
    dj += [pool.submit(design_cell, c, "A", nz, "-noise%g" % nz) for c in noise_cells for nz in noises]
    dj += [pool.submit(design_cell, c, "B", 0.01, "-B") for c in b_cells]
    designs = dict(f.result() for f in dj)
    t_design = time.time() - t0

    def dfile(c, tag=""):
        g = designs[(c, tag)]
        return os.path.join(SCRATCH, cell_key(c) + tag, best_param(g) + ".json")

    jobs = []
    for c in cells:
        band, pixel_lod, r, n = c
        for obj in ("usaf", "demo"):
            jobs.append(pool.submit(heldout, c, "raster", {"type": "raster"}, obj))
            jobs.append(pool.submit(heldout, c, "design", {"type": "design", "file": dfile(c)}, obj))
            jobs.append(pool.submit(heldout, c, "shifted", {"type": "design", "frames": shifted_raster(r, n)}, obj))
    for c, s in fine:
        band, pixel_lod, r, n = c
        for obj in ("usaf", "demo"):
            jobs.append(pool.submit(heldout, c, "raster", {"type": "raster"}, obj, 0.01, s))
            jobs.append(pool.submit(heldout, c, "design", {"type": "design", "file": dfile(c)}, obj, 0.01, s))
            jobs.append(pool.submit(heldout, c, "shifted", {"type": "design", "frames": shifted_raster(c[2], c[3])},
                                    obj, 0.01, s))
    for c in noise_cells:
        for nz in noises:
            tag = "-noise%g" % nz
            for obj in ("usaf", "demo"):
                jobs.append(pool.submit(heldout, c, "raster", {"type": "raster"}, obj, nz, 1, tag))
                jobs.append(pool.submit(heldout, c, "design", {"type": "design", "file": dfile(c, tag)}, obj, nz, 1, tag))
                jobs.append(pool.submit(heldout, c, "shifted", {"type": "design", "frames": shifted_raster(c[2], c[3])},
                                        obj, nz, 1, tag))
    # The lowest noise, where the discrete model's registration effect is largest, with the sky 4x finer too.
    for c in noise_cells:
        tag = "-noise%g" % min(noises)
        for obj in ("usaf", "demo"):
            jobs.append(pool.submit(heldout, c, "raster", {"type": "raster"}, obj, min(noises), 4, tag))
            jobs.append(pool.submit(heldout, c, "design", {"type": "design", "file": dfile(c, tag)}, obj, min(noises), 4,
                                    tag))
            jobs.append(pool.submit(heldout, c, "shifted", {"type": "design", "frames": shifted_raster(c[2], c[3])},
                                    obj, min(noises), 4, tag))
    for c in b_cells:
        for obj in ("usaf", "demo"):
            jobs.append(pool.submit(heldout, c, "design", {"type": "design", "file": dfile(c, "-B")}, obj, 0.01, 1, "-B"))
    # The TV gain of the shifted raster in K 3.74 r = 4 N = 4 (issue 25's open question): TV to convergence.
    tv_cell = ("K", 3.74, 4, 4)
    if not a.quick:
        for obj in ("usaf", "demo"):
            for s in (1, 4):
                jobs.append(pool.submit(heldout, tv_cell, "raster", {"type": "raster"}, obj, 0.01, s, "-tv400", 400))
                jobs.append(pool.submit(heldout, tv_cell, "shifted", {"type": "design", "frames": shifted_raster(4, 4)},
                                        obj, 0.01, s, "-tv400", 400))
    held = dict(f.result() for f in jobs)
    wall = time.time() - t0

    def h(c, label, obj, m, sky=1, tag=""):
        return held[(cell_key(c) + tag, label, obj, sky)][m]

    def delta(c, label, m, sky=1, tag="", base_tag=None):
        bt = tag if base_tag is None else base_tag
        v = [h(c, label, o, m, sky, tag) - h(c, "raster", o, m, sky, bt) for o in ("usaf", "demo")]
        return "%+.2f / %+.2f" % tuple(v)

    def fmt(x):
        return "%+.2f +- %.2f" % (x["db"], x["stderr_db"] or 0)

    def advice_of(g):
        best = best_param(g)
        x = g[best]["gain"]
        return "design (%s)" % best if x["db"] >= 0.2 and x["db"] > 2 * (x["stderr_db"] or 0) else "raster"

    lines = ["<!-- produced by: bench/design_regimes.py%s -->" % (" --quick" if a.quick else ""),
             "# Where a designed phase beats the raster (issue 25)", "",
             "Command: `bench/design_regimes.py%s` (from the repository root, Release build), %s UTC, git %s. "
             "Wall time %.0f s (designs %.0f s), 2 jobs, `uptime` at the end: `%s`." % (
                 " --quick" if a.quick else "", time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
                 subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True).stdout.strip(), wall, t_design,
                 subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()), "",
             "System: the paper-8m preset (8 m, 17x17 DM, 16x16 SH, 800 Hz, r0 = 15 cm at 550 nm) with the science "
             "band K, H or J and the K-band camera's pixel (56.7 mas = 1.0, 1.375, 1.76 lambda/D), or a 3.74 lambda/D "
             "pixel at K (the paper bench's sampling); analytic AO; 64 x 64 camera px frames (32 x 32 at r = 8); the "
             "paper's noise (Gaussian, 1 % of the brightest noiseless pixel) unless stated. HR pixel = pixel/r "
             "lambda/D; Nyquist is 0.5.", "",
             "Expected gain: `aosr design --param P --modes 20 --starts 1 --iterations 25 --realisations 1 --screens 2 "
             "--validation-realisations 3 --min-gain 0` (objective A, default gradient prior, lambda 1e-2): "
             "10 log10(MSE_raster / MSE_design) on 3 fresh AO realisations, +- its standard error over them. r = 8 "
             "cells (quick-style reduction): tip/tilt only, 15 iterations, 32 px frames. Held-out: USAF and the demo "
             "truth at sky/noise seed 777 (the design saw neither), simulated with the raster, the better design, "
             "and the raster moved by half an HR pixel (1/(2r) camera px in y and x, no optimisation); "
             "`aosr reconstruct -m tikhonov` (GCV) and `-m tv --iterations 60`; PSNR by `aosr evaluate --crop 4r`.", "",
             "| band | pixel [lambda/D] | HR pixel [lambda/D] | r | N | A gain tip/tilt [dB] | A gain Zernike [dB] | "
             "advice | Tikhonov design - raster [dB] | TV design - raster [dB] | Tikhonov shifted - raster [dB] | "
             "TV shifted - raster [dB] | raster Tikhonov / TV [dB] |",
             "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|"]
    rows = []
    for c in cells:
        band, pixel_lod, r, n = c
        g = designs[(c, "")]
        ras = "%.2f / %.2f, %.2f / %.2f" % (h(c, "raster", "usaf", "tikhonov"), h(c, "raster", "usaf", "tv"),
                                            h(c, "raster", "demo", "tikhonov"), h(c, "raster", "demo", "tv"))
        lines.append("| %s | %.3g | %.3g | %d | %d | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            band, pixel_lod, pixel_lod / r, r, n, fmt(g["tiptilt"]["gain"]),
            fmt(g["zernike"]["gain"]) if "zernike" in g else "-", advice_of(g),
            delta(c, "design", "tikhonov"), delta(c, "design", "tv"), delta(c, "shifted", "tikhonov"),
            delta(c, "shifted", "tv"), ras))
        rows.append({"cell": cell_key(c), "gain": {p: g[p]["gain"] for p in g},
                     "held": {"%s/%s" % (l, o): held[(cell_key(c), l, o, 1)]
                              for l in ("raster", "design", "shifted") for o in ("usaf", "demo")}})
    lines += ["", "Held-out columns: USAF / demo truth. Raw numbers: `build/regimes/results.json`; the picture: "
              "`build/bench/design_regimes_plot build/regimes/results.json bench/results/design_regimes.png`.", ""]

    lines += ["### A sky finer than the HR grid (`sky_oversampling`)", "",
              "The same held-out scenes with the sky rendered s times finer than the HR grid (scene field "
              "`sky_oversampling`: objects at r*s per camera pixel, PSFs sampled at HR pitch / s, camera pixels "
              "integrating the fine grid); reconstructed on the usual HR grid with the PSFs sampled at the HR pitch; "
              "scored against the fine sky integrated over HR pixels. s = 1 is the map above (same seeds, same "
              "designs).", "",
              "| cell | s | Tikhonov design - raster | TV design - raster | Tikhonov shifted - raster | "
              "TV shifted - raster | raster Tikhonov / TV (USAF) | raster at s minus at s = 1, Tikhonov / TV (USAF) |",
              "|---|---:|---:|---:|---:|---:|---:|---:|"]
    fine_rows = []
    for c, s in sorted(set([(c, 1) for c, _ in fine] + fine), key=lambda x: (cells.index(x[0]), x[1])):
        lines.append("| %s | %d | %s | %s | %s | %s | %.2f / %.2f | %s |" % (
            cell_key(c), s, delta(c, "design", "tikhonov", s), delta(c, "design", "tv", s),
            delta(c, "shifted", "tikhonov", s), delta(c, "shifted", "tv", s),
            h(c, "raster", "usaf", "tikhonov", s), h(c, "raster", "usaf", "tv", s),
            "%+.2f / %+.2f" % (h(c, "raster", "usaf", "tikhonov", s) - h(c, "raster", "usaf", "tikhonov"),
                               h(c, "raster", "usaf", "tv", s) - h(c, "raster", "usaf", "tv"))))
        fine_rows.append({"cell": cell_key(c), "s": s, "held": {"%s/%s" % (l, o): held[(cell_key(c), l, o, s)]
                                                                for l in ("raster", "design", "shifted")
                                                                for o in ("usaf", "demo")}})
    lines += ["", "Columns: USAF / demo, dB."]

    lines += ["", "### Noise level (objective A with lambda = 1e-2 (noise / 1 %)^2; held-out at that noise)", "",
              "| cell | noise [% of peak] | A gain tip/tilt | A gain Zernike | advice | Tikhonov design - raster | "
              "TV design - raster | Tikhonov shifted - raster | TV shifted - raster | raster Tikhonov / TV (USAF) |",
              "|---|---:|---:|---:|---|---:|---:|---:|---:|---:|"]
    noise_rows = []
    for c in noise_cells:
        for nz in sorted(noises + (0.01,)):
            tag = "" if nz == 0.01 else "-noise%g" % nz
            g = designs[(c, tag)]
            lines.append("| %s | %g | %s | %s | %s | %s | %s | %s | %s | %.2f / %.2f |" % (
                cell_key(c), 100 * nz, fmt(g["tiptilt"]["gain"]), fmt(g["zernike"]["gain"]) if "zernike" in g else "-",
                advice_of(g), delta(c, "design", "tikhonov", 1, tag), delta(c, "design", "tv", 1, tag),
                delta(c, "shifted", "tikhonov", 1, tag), delta(c, "shifted", "tv", 1, tag),
                h(c, "raster", "usaf", "tikhonov", 1, tag), h(c, "raster", "usaf", "tv", 1, tag)))
            noise_rows.append({"cell": cell_key(c), "noise": nz, "gain": {p: g[p]["gain"] for p in g}})
            if nz == min(noises):
                lines.append("| %s | %g, sky 4x finer | (same design) | | | %s | %s | %s | %s | %.2f / %.2f |" % (
                    cell_key(c), 100 * nz, delta(c, "design", "tikhonov", 4, tag), delta(c, "design", "tv", 4, tag),
                    delta(c, "shifted", "tikhonov", 4, tag), delta(c, "shifted", "tv", 4, tag),
                    h(c, "raster", "usaf", "tikhonov", 4, tag), h(c, "raster", "usaf", "tv", 4, tag)))

    lines += ["", "### Objective B (MAP loss) against A", "",
              "`aosr design --objective B --param tiptilt --starts 1 --iterations 10 --training-scenes 2 --noise-sigma "
              "0.01 --validation-realisations 2 --min-gain 0` (charbonnier-TV MAP, l1 loss, dead-leaves training); its "
              "gain is on 3 fresh dead-leaves scenes with fresh noise and AO (one pooled sample, so the advice is "
              "design when the gain is >= 0.2 dB, the map's threshold). Held-out as above (the raster runs are the "
              "map's).", "",
              "| cell | B gain tip/tilt [dB] | B advice | A gain tip/tilt [dB] | Tikhonov B design - raster | "
              "TV B design - raster | Tikhonov A design - raster | TV A design - raster | B design's shifts [camera px] |",
              "|---|---:|---|---:|---:|---:|---:|---:|---|"]
    b_rows = []
    for c in b_cells:
        gb, ga = designs[(c, "-B")], designs[(c, "")]
        x = gb["tiptilt"]["gain"]
        shifts = " ".join("(%.2f, %.2f)" % tuple(f["shift_px"]) for f in gb["tiptilt"]["frames"])
        lines.append("| %s | %+.2f | %s | %s | %s | %s | %s | %s | %s |" % (
            cell_key(c), x["db"], "design" if x["db"] >= 0.2 else "raster", fmt(ga["tiptilt"]["gain"]),
            delta(c, "design", "tikhonov", 1, "-B", ""), delta(c, "design", "tv", 1, "-B", ""),
            delta(c, "design", "tikhonov"), delta(c, "design", "tv"), shifts))
        b_rows.append({"cell": cell_key(c), "gain_b": x, "gain_a": ga["tiptilt"]["gain"]})

    if not a.quick:
        lines += ["", "### TV to convergence in K 3.74 lambda/D, r = 4, N = 4", "",
                  "`aosr reconstruct -m tv --iterations 400` (converged in every run below) against the map's 60.", "",
                  "| s | TV-60 shifted - raster | TV-400 shifted - raster | TV-400 raster (USAF / demo) |",
                  "|---:|---:|---:|---:|"]
        for s in (1, 4):
            lines.append("| %d | %s | %s | %.2f / %.2f |" % (
                s, delta(tv_cell, "shifted", "tv", s), delta(tv_cell, "shifted", "tv", s, "-tv400"),
                h(tv_cell, "raster", "usaf", "tv", s, "-tv400"), h(tv_cell, "raster", "demo", "tv", s, "-tv400")))

    if not a.quick:
        lines += band_tables()

    lines += ["", "### Per-frequency transfer: |H_half(f)| / |H_0(f)|, a PSF half an HR pixel off the HR samples against one "
              "on them (`transfer_lines` in the script)", ""] + transfer_lines() + [""]
    os.makedirs(SCRATCH, exist_ok=True)
    json.dump({"rows": rows, "fine": fine_rows, "noise": noise_rows, "objective_b": b_rows, "wall_seconds": wall},
              open(os.path.join(SCRATCH, "results.json"), "w"), indent=1)
    text = "\n".join(lines)
    if a.out:
        old = open(a.out).read() if os.path.exists(a.out) else ""
        marker = "<!-- analysis -->"
        tail = old[old.index(marker):] if marker in old else ""
        open(a.out, "w").write(text + ("\n" + tail if tail else ""))
    print(text)


if __name__ == "__main__":
    sys.exit(main())
