#!/usr/bin/env python3
"""How far the linear reconstructors' kernels reach: what a tiling needs for the issue's 1e-6 (issue 32).

A tiled reconstruction of a linear method differs from the whole-grid one by what the windows cut off. With one
PSF per frame over the field and uniform weights, the whole-grid Tikhonov estimate and the target-PSF linear output
are sums of per-frame convolutions, x = sum_i k_i * (upsampled frame i), and a pixel's value is cut by the part of
k_i beyond the window. This bench measures that part: the response to a unit pixel in frame 0 at the grid's
centre (all other frames zero), on a periodic grid large enough that the response has died out before it wraps.

Scene: r = 2, N = 4 frames on the 2 x 2 half-pixel raster, Gaussian PSFs of sigma 1.5 HR px (16 x 16 kernels),
384^2 HR grid (192 camera px), no noise; the settings of tests/solvers/tiling_test.cpp's scene. Rows: Tikhonov
(gradient prior) at fixed lambda (1e-3, the test's; 7e-3, the scene's GCV value), and the linear output at its
automatic target and kappa.

For each reach R (camera px, Chebyshev distance from the impulse): the tail's L1 norm over the whole response's
(an upper bound on the relative error of any pixel whose data beyond R were cut, for data of one sign and
magnitude), and its largest value over the response's peak.

Command: PYTHONPATH=build/python /usr/bin/python3 bench/kernel_reach.py   (seconds)
Writes bench/results/kernel_reach.md.
"""
import os
import time

import numpy as np

import aosr
from results_file import write_keeping_analysis

R_CAMERA = (4, 8, 12, 16, 20, 24, 28, 32, 48)


def scene():
    r, hr = 2, 384
    yy, xx = np.mgrid[-8:8, -8:8]
    psfs = []
    for dy, dx in ((0, 0), (0, 1), (1, 0), (1, 1)):
        k = np.exp(-((yy - dy / 2) ** 2 + (xx - dx / 2) ** 2) / (2 * 1.5 ** 2))
        psfs.append(k / k.sum())
    frames = np.zeros((4, hr // r, hr // r))
    frames[0, hr // r // 2, hr // r // 2] = 1.0
    return aosr.Dataset.from_arrays(frames, np.array(psfs), r=r), r, hr


def reach(image, r, hr):
    k = np.asarray(image)
    c = hr // 2
    d = np.maximum(np.abs(np.arange(hr)[:, None] - c), np.abs(np.arange(hr)[None, :] - c)) / r
    total, peak = np.abs(k).sum(), np.abs(k).max()
    return [(np.abs(k[d > R]).sum() / total, np.abs(k[d > R]).max() / peak) for R in R_CAMERA]


def main():
    ds, r, hr = scene()
    rows = []
    start = time.time()
    for label, method, options in (("tikhonov, lambda 1e-3", "tikhonov", {"lambda": 1e-3}),
                                   ("tikhonov, lambda 7e-3", "tikhonov", {"lambda": 7e-3}),
                                   ("linear (automatic target, kappa)", "linear", {})):
        rec = aosr.reconstruct(ds, method, **options)
        rows.append((label, reach(rec.image, r, hr)))
        print(label, "done")
    lines = ["# How far the linear reconstructors' kernels reach (issue 32)", "",
             "Command: `PYTHONPATH=build/python /usr/bin/python3 bench/kernel_reach.py` (%.0f s). The response to a "
             "unit pixel of frame 0 on a 384² HR periodic grid, r = 2, N = 4 (2 x 2 raster), Gaussian PSFs of σ "
             "1.5 HR px: the scene of tests/solvers/tiling_test.cpp. For each reach R (camera px, Chebyshev "
             "distance): the tail's L1 norm / the response's, and (in brackets) its largest value / the peak. "
             "Details: the top of bench/kernel_reach.py." % (time.time() - start), "",
             "| method | " + " | ".join("R = %d" % R for R in R_CAMERA) + " |",
             "|---|" + "---|" * len(R_CAMERA)]
    for label, values in rows:
        lines.append("| %s | " % label + " | ".join("%.1e (%.0e)" % v for v in values) + " |")
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "kernel_reach.md")
    write_keeping_analysis(out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
