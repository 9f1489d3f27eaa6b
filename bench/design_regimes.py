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
--quick: K and J band at r = 2 only (a smoke run, ~2 min). Two jobs at a time (the machine has 2 cores).
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


def scene(name, band, pixel_lod, r, n, offsets, obj, seed):
    tel = json.loads(json.dumps(PRESET))
    tel["name"] = "paper-8m-" + band
    tel["science"] = {"wavelength_m": BANDS[band], "camera_pixel_lambda_over_d": pixel_lod}
    objects = {"usaf": {"type": "usaf", "fill": 0.9, "first_group": -2, "last_group": 1, "flux": {"peak_e": 1000}},
               "demo": {"type": "demo", "flux": {"peak_e": 1000}}}[obj]
    return {"name": name, "seed": seed, "telescope": tel, "frames": n, "r": r, "ao": {"mode": "analytic"},
            "offsets": offsets, "objects": [objects],
            "detector": {"frame_px": 64, "noise": "peak-fraction", "peak_noise_fraction": 0.01, "saturation": False}}


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


def cell_key(c):
    return "%s-p%.2f-r%d-N%d" % c


def design_cell(c):
    band, pixel_lod, r, n = c
    d = os.path.join(SCRATCH, cell_key(c))
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, "instrument.json")
    json.dump(scene(cell_key(c), band, pixel_lod, r, n, {"type": "raster"}, "usaf", 1), open(path, "w"), indent=1)
    out = {}
    for param in ("tiptilt", "zernike"):
        t = time.time()
        j = run_json(["design", path, "--param", param, "--modes", 20, "--starts", 1, "--iterations", 25,
                      "--realisations", 1, "--screens", 2, "--validation-realisations", 3, "--threads", 1,
                      "--min-gain", 0, "-o", os.path.join(d, param + ".json")])
        out[param] = {"gain": j["gain"], "seconds": time.time() - t, "frames": j["design"]["frames"]}
    return c, out


def heldout(c, label, offsets, obj):
    band, pixel_lod, r, n = c
    d = os.path.join(SCRATCH, cell_key(c), label + "-" + obj)
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, "scene.json")
    # Fresh sky and noise: seed 777 (the designs saw seed 1's AO screens and no sky at all).
    json.dump(scene("heldout", band, pixel_lod, r, n, offsets, obj, 777), open(path, "w"), indent=1)
    run_json(["simulate", path, "-o", d])
    res = {}
    for m, extra in (("tikhonov", []), ("tv", ["--iterations", 60])):
        est = os.path.join(d, m + ".fits")
        run_json(["reconstruct", d, "-m", m, "-o", est] + extra)
        ev = run_json(["evaluate", "--manifest", d, "--estimate", est, "--crop", 4 * r])
        res[m] = ev["psnr_db"] if "psnr_db" in ev else ev["psnr"]
    return (cell_key(c), label, obj), res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    t0 = time.time()
    if a.quick:
        cells = [("K", 1.0, 2, 4), ("J", 1.76, 2, 4)]
    else:
        cells = [("K", 1.0, 2, 4), ("H", 1.375, 2, 4), ("J", 1.76, 2, 4),
                 ("K", 1.0, 4, 4), ("H", 1.375, 4, 4), ("J", 1.76, 4, 4),
                 ("K", 1.0, 4, 16), ("J", 1.76, 4, 16),
                 ("K", 3.74, 4, 4), ("K", 3.74, 4, 16)]
    pool = cf.ThreadPoolExecutor(max_workers=2)
    designs = dict(f.result() for f in [pool.submit(design_cell, c) for c in cells])
    jobs = []
    for c in cells:
        band, pixel_lod, r, n = c
        best = max(designs[c], key=lambda p: designs[c][p]["gain"]["db"])
        dfile = os.path.join(SCRATCH, cell_key(c), best + ".json")
        # The raster moved by half an HR pixel: the classic raster's shifts (for N = k^2 a k x k lattice of pitch
        # 1/k camera px centred on zero, as the scenes' "raster" offsets: +-1/4 for N = 4 at every r) plus 1/(2r)
        # camera px in y and x.
        k = int(round(math.sqrt(n)))
        shifted = [{"shift_px": [((i // k) - (k - 1) / 2) / k + 0.5 / r, ((i % k) - (k - 1) / 2) / k + 0.5 / r]}
                   for i in range(n)]
        for obj in ("usaf", "demo"):
            jobs.append(pool.submit(heldout, c, "raster", {"type": "raster"}, obj))
            jobs.append(pool.submit(heldout, c, "design", {"type": "design", "file": dfile}, obj))
            jobs.append(pool.submit(heldout, c, "shifted", {"type": "design", "frames": shifted}, obj))
    held = dict(f.result() for f in jobs)
    wall = time.time() - t0

    lines = ["<!-- produced by: bench/design_regimes.py%s -->" % (" --quick" if a.quick else ""),
             "# Where a designed phase beats the raster (issue 25)", "",
             "Command: `bench/design_regimes.py%s` (from the repository root, Release build), %s UTC, git %s. "
             "Wall time %.0f s, 2 jobs, `uptime` at the end: `%s`." % (
                 " --quick" if a.quick else "", time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
                 subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True).stdout.strip(), wall,
                 subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()), "",
             "System: the paper-8m preset (8 m, 17x17 DM, 16x16 SH, 800 Hz, r0 = 15 cm at 550 nm) with the science "
             "band K, H or J and the K-band camera's pixel (56.7 mas = 1.0, 1.375, 1.76 lambda/D), or a 3.74 lambda/D "
             "pixel at K (the paper bench's sampling); analytic AO; 64 x 64 camera px frames; the paper's noise "
             "(Gaussian, 1 % of the brightest noiseless pixel). HR pixel = pixel/r lambda/D; Nyquist is 0.5.", "",
             "Expected gain: `aosr design --param P --modes 20 --starts 1 --iterations 25 --realisations 1 --screens 2 "
             "--validation-realisations 3 --min-gain 0` (objective A, default gradient prior): 10 log10(MSE_raster / "
             "MSE_design) on 3 fresh AO realisations, +- its standard error over them. Held-out: USAF and the demo "
             "truth at sky/noise seed 777 (the design saw neither), simulated with the raster, the better of the two "
             "designs, and the raster moved by half an HR pixel (1/(2r) camera px in y and x, no optimisation); "
             "`aosr reconstruct -m tikhonov` (GCV) and `-m tv --iterations 60`; PSNR by `aosr evaluate --crop 4r`.", "",
             "| band | pixel [lambda/D] | HR pixel [lambda/D] | r | N | A gain tip/tilt [dB] | A gain Zernike [dB] | "
             "advice | Tikhonov design - raster [dB] | TV design - raster [dB] | Tikhonov shifted - raster [dB] | "
             "TV shifted - raster [dB] | raster Tikhonov / TV [dB] |",
             "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|"]
    rows = []
    for c in cells:
        band, pixel_lod, r, n = c
        g = {p: designs[c][p]["gain"] for p in designs[c]}
        best = max(g, key=lambda p: g[p]["db"])
        advice = "design (%s)" % best if g[best]["db"] >= 0.2 and g[best]["db"] > 2 * (g[best]["stderr_db"] or 0) else "raster"

        def delta(label, m):
            v = [held[(cell_key(c), label, o)][m] - held[(cell_key(c), "raster", o)][m] for o in ("usaf", "demo")]
            return "%+.2f / %+.2f" % tuple(v)

        def fmt(x):
            return "%+.2f +- %.2f" % (x["db"], x["stderr_db"] or 0)

        ras = "%.2f / %.2f, %.2f / %.2f" % (held[(cell_key(c), "raster", "usaf")]["tikhonov"],
                                            held[(cell_key(c), "raster", "usaf")]["tv"],
                                            held[(cell_key(c), "raster", "demo")]["tikhonov"],
                                            held[(cell_key(c), "raster", "demo")]["tv"])
        lines.append("| %s | %.3g | %.3g | %d | %d | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            band, pixel_lod, pixel_lod / r, r, n, fmt(g["tiptilt"]), fmt(g["zernike"]), advice,
            delta("design", "tikhonov"), delta("design", "tv"), delta("shifted", "tikhonov"), delta("shifted", "tv"),
            ras))
        rows.append({"cell": cell_key(c), "gain": g, "held": {"%s/%s" % (l, o): held[(cell_key(c), l, o)]
                                                              for l in ("raster", "design", "shifted")
                                                              for o in ("usaf", "demo")}})
    lines += ["", "Held-out columns: USAF / demo truth. Raw numbers: `build/regimes/results.json`; the picture: "
              "`build/bench/design_regimes_plot build/regimes/results.json bench/results/design_regimes.png`.", "",
              "### Per-frequency transfer: |H_half(f)| / |H_0(f)|, a PSF half an HR pixel off the HR samples against one "
              "on them (`transfer_lines` in the script)", ""] + transfer_lines() + [""]
    os.makedirs(SCRATCH, exist_ok=True)
    json.dump({"rows": rows, "wall_seconds": wall}, open(os.path.join(SCRATCH, "results.json"), "w"), indent=1)
    text = "\n".join(lines)
    if a.out:
        old = open(a.out).read() if os.path.exists(a.out) else ""
        marker = "<!-- analysis -->"
        tail = old[old.index(marker):] if marker in old else ""
        open(a.out, "w").write(text + ("\n" + tail if tail else ""))
    print(text)


if __name__ == "__main__":
    sys.exit(main())
