#!/usr/bin/python3
"""Benchmark of the live quick-look (`aosr watch`, issue 34 item 3), printing a markdown table (and writing it with
--out).

A writer process plays the camera: FRAMES frames (default 1000) of 128² px at RATE frames per second (default 50),
cycling through N = 4 DM phases, written with astropy straight into the watched folder (in place, no rename: the
case where a reader could see a half-written file) or, with --atomic, with aosr.write_fits (a temporary name, then a
rename). `aosr watch` (the real executable, its own process) reconstructs them at r = 4 (512² outputs) with the
linear methods (Tikhonov with a fixed lambda, the target-PSF output), on 1 and 2 threads, and must account for every
file: the table reports lost, half-read (rejected) and late files (all must be 0), the latency from each file's
completion (its modification time) to the quick-look FITS and PNG renamed into place (p50, p95, p99, max; the
first output, which builds the slot filter, apart), and the median stages (read, reconstruct, write). Only the
newest output is written when files queue up (solvers/quick_look.hpp): the table counts the outputs written and
those superseded.

The model dataset: Gaussian PSFs (σ 1.3 HR px) on the 2 × 2 raster of half-pixel shifts, gain 2, bias 100, a known
noise σ; the frames: a field of stars and a moving blob, noise σ 1 e⁻.

Usage: /usr/bin/python3 bench/watch.py [--build build] [--out bench/results/watch.md] [--frames 1000] [--rate 50]
       [--threads 1,2] [--methods tikhonov,linear] [--atomic] [--work DIR]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

R = 4
LR = 128
N = 4
GAIN, BIAS, SIGMA_E = 2.0, 100.0, 1.0
SHIFTS = [(0.0, 0.0), (0.0, 2.0), (2.0, 0.0), (2.0, 2.0)]  # HR px: half a camera pixel

WRITER = r"""
import sys, time
import numpy as np
folder, npy, rate, atomic, frames_total = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4] == "1", int(sys.argv[5])
cycle = np.load(npy)
if atomic:
    import aosr
else:
    from astropy.io import fits
t0 = time.monotonic()
late = 0
for j in range(frames_total):
    f = cycle[j % len(cycle)]
    path = f"{folder}/frame_{j:06d}.fits"
    if atomic:
        aosr.write_fits(path, f, {"DMPHASE": j % 4, "TSEC": j / rate}, dtype="float64")
    else:
        h = fits.Header()
        h["DMPHASE"] = j % 4
        h["TSEC"] = j / rate
        fits.writeto(path, f, h)
    wait = t0 + (j + 1) / rate - time.monotonic()
    if wait < 0:
        late += 1
    time.sleep(max(0.0, wait))
print(late)
"""


def psfs():
    y, x = np.mgrid[0:32, 0:32]
    out = []
    for dy, dx in SHIFTS:
        k = np.exp(-((y - 16 - dy) ** 2 + (x - 16 - dx) ** 2) / (2 * 1.3 ** 2))
        out.append(k / k.sum())
    return np.array(out)


def frames(count, rng):
    """ADU frames: stars plus a blob moving 2 HR px per frame, phase j % 4; noise SIGMA_E."""
    hr = (R * LR, R * LR)
    x = np.zeros(hr)
    ys, xs = rng.integers(0, hr[0], 300), rng.integers(0, hr[1], 300)
    x[ys, xs] = rng.uniform(200, 5000, 300)
    yy, xx = np.mgrid[0:hr[0], 0:hr[1]]
    p = psfs()
    out = []
    for j in range(count):
        blob = 50.0 * np.exp(-((yy - 256.0) ** 2 + (xx - 40.0 - 2 * j) ** 2) / 50.0)
        k = np.zeros(hr)
        k[:32, :32] = p[j % 4]
        k = np.roll(k, (-16, -16), axis=(0, 1))
        blurred = np.fft.irfft2(np.fft.rfft2(x + blob) * np.fft.rfft2(k), s=hr)
        e = blurred.reshape(LR, R, LR, R).sum(axis=(1, 3)) + SIGMA_E * rng.standard_normal((LR, LR))
        out.append(e / GAIN + BIAS)
    return np.array(out)


def write_model(aosr, folder, model_frames):
    folder.mkdir(parents=True)
    aosr.write_fits(folder / "frames.fits", model_frames, dtype="float64")
    aosr.write_fits(folder / "psfs.fits", psfs(), dtype="float64")
    m = {"format": "aosr-manifest", "version": 1, "frames": "frames.fits", "psfs": "psfs.fits", "r": R,
         "gain_e_per_adu": GAIN, "bias_adu": BIAS, "noise": {"model": "peak-fraction", "sigma_e": SIGMA_E}}
    (folder / "manifest.json").write_text(json.dumps(m))


def run(args, aosr_cli, work, model, cycle_npy, method, threads):
    camera = work / f"camera_{method}_{threads}"
    out = work / f"out_{method}_{threads}"
    shutil.rmtree(camera, ignore_errors=True)
    shutil.rmtree(out, ignore_errors=True)
    camera.mkdir()
    cmd = [aosr_cli, "watch", str(camera), "--model", str(model), "-o", str(out), "-m", method, "--time-key", "TSEC",
           "--frames", str(args.frames), "--idle-timeout", "30", "--threads", str(threads), "--json"]
    if method == "tikhonov":
        cmd += ["--lambda", "1e-4"]
    watcher = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for _ in range(3000):  # the watcher is ready when its log exists
        if (out / "watch.jsonl").exists():
            break
        time.sleep(0.01)
    env = dict(os.environ)
    writer = subprocess.run([sys.executable, "-c", WRITER, str(camera), str(cycle_npy), str(args.rate),
                             "1" if args.atomic else "0", str(args.frames)], capture_output=True, text=True, env=env)
    if writer.returncode != 0:
        watcher.kill()
        raise RuntimeError("writer failed:\n" + writer.stderr)
    stdout, stderr = watcher.communicate(timeout=120)
    if watcher.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{stdout}\n{stderr}")
    s = json.loads(stdout[stdout.index("{"):])
    log = [json.loads(line) for line in (out / "watch.jsonl").read_text().splitlines()]
    written = args.frames
    seen = {os.path.basename(e["file"]) for e in log}
    s["lost"] = written - len(seen)
    s["writer_late"] = int(writer.stdout.strip() or 0)
    shutil.rmtree(camera, ignore_errors=True)
    return s


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default="build")
    ap.add_argument("--out", default="")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--rate", type=float, default=50.0)
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--methods", default="tikhonov,linear")
    ap.add_argument("--atomic", action="store_true")
    ap.add_argument("--work", default="")
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(args.build, "python"))
    import aosr  # noqa: E402  (the build's module)
    if not args.atomic:
        import astropy  # noqa: F401  (the in-place writer)
    aosr_cli = os.path.abspath(os.path.join(args.build, "aosr"))
    import pathlib
    work = pathlib.Path(args.work or tempfile.mkdtemp(prefix="aosr_watch_bench_"))
    work.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(34)
    cycle = frames(40, rng)  # the writer cycles through these (10 cycles of the moving blob)
    write_model(aosr, work / "model", cycle[:4])
    np.save(work / "cycle.npy", cycle)
    rows = []
    for method in args.methods.split(","):
        for threads in [int(t) for t in args.threads.split(",")]:
            s = run(args, aosr_cli, work, work / "model", work / "cycle.npy", method, threads)
            lat = s["latency_ms"]
            rows.append(f"| {method} | {threads} | {args.frames} | {s['used']} | {s['lost']} | {s['rejected']} | "
                        f"{s['late']} | {s['incomplete']} | {s['written']} | {s['superseded']} | "
                        f"{s['first_latency_ms']:.0f} | {lat['p50']:.1f} | "
                        f"{lat['p95']:.1f} | {lat['p99']:.1f} | {lat['max']:.1f} | {s['read_ms_p50']:.2f} | "
                        f"{s['reconstruct_ms_p50']:.2f} | {s['write_ms_p50']:.2f} | {s['writer_late']} |")
            print(rows[-1], flush=True)
    writer_kind = "aosr.write_fits (temporary name, rename)" if args.atomic else "astropy, in place (no rename)"
    text = "\n".join([
        f"`aosr watch`: {args.frames} frames of {LR}² px at {args.rate:g} frames/s, N = {N} phases, r = {R} "
        f"({R * LR}² outputs), sliding window; writer: {writer_kind}; inotify. Latency: file complete (mtime) → "
        "quicklook.fits and quicklook.png renamed into place. Stages: medians per output.",
        "",
        "| method | threads | files | used | lost | rejected | late | incomplete | outputs written | superseded | "
        "first output ms | p50 ms | p95 ms | p99 ms | max ms | read ms | reconstruct ms | write ms | "
        "writer behind schedule |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ] + rows) + "\n"
    print()
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(f"<!-- /usr/bin/python3 bench/watch.py --build {args.build} --frames {args.frames} "
                    f"--rate {args.rate:g}{' --atomic' if args.atomic else ''} -->\n" + text)
    if not args.work:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
