#!/usr/bin/python3
"""Benchmark of the Python package (issue 17 targets), printing a markdown table (and writing it with --out):

1. aosr.reconstruct from Python against the same library call in C++ (python/tests/aosr_py_reference.cpp:
   ProblemFromDataset + Reconstruct on an already loaded dataset) on a 512^2 problem (paper-sim-r4: 128^2
   frames, r = 4, N = 4): best of K runs each, and the images compared bit for bit. Target: within 5 %.
2. 16 datasets reconstructed by aosr.distributed.reconstruct_many on a 2-worker LocalCluster against the serial
   loop (the same task function in one process, 1 aosr thread per task as on the workers; and, for context,
   the serial loop with 2 aosr threads per task). Target: >= 1.7x.

Usage: /usr/bin/python3 bench/python_bench.py [--build build] [--out bench/results/python.md] [--quick]
Needs the build's aosr package (PYTHONPATH=<build>/python, set here from --build) and its executables.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(root, "build"))
    ap.add_argument("--out", default=None, help="also write the table here (e.g. bench/results/python.md)")
    ap.add_argument("--quick", action="store_true", help="fewer repeats and datasets (checks the script)")
    args = ap.parse_args()
    build = os.path.abspath(args.build)
    sys.path.insert(0, os.path.join(build, "python"))
    import numpy as np
    import aosr
    import aosr.distributed as ad

    reference = os.path.join(build, "python", "aosr_py_reference")
    repeats = 2 if args.quick else 5
    work = tempfile.mkdtemp(prefix="aosr-python-bench-")
    lines = []
    say = lambda s="": (print(s, flush=True), lines.append(s))  # noqa: E731
    load = os.getloadavg()
    say("# Python package: overhead against C++, and Dask scale-out")
    say()
    say(f"`/usr/bin/python3 bench/python_bench.py --build {os.path.relpath(build, root)}"
        f"{' --quick' if args.quick else ''}` on {os.cpu_count()} cores; load average before the run "
        f"{load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1/5/15 min; other jobs share the machine).")
    say()
    try:
        # ---- 1. Python vs C++ on 512^2 ----------------------------------------------------------------------
        ds_dir = os.path.join(work, "r4")
        aosr.simulate(aosr.load_scene(os.path.join(root, "data", "scenes", "paper-sim-r4.json")), output=ds_dir)
        ds = aosr.open_dataset(ds_dir)
        say(f"## 1. aosr.reconstruct vs the same call in C++ (paper-sim-r4: {len(ds)} frames of "
            f"{ds.frame_shape[0]}x{ds.frame_shape[1]}, r = {ds.r}, HR {ds.hr_shape[0]}x{ds.hr_shape[1]}; "
            f"{aosr.threads()} aosr threads, best of {repeats})")
        say()
        say("| method | C++ [s] | Python [s] | Python / C++ | same bits |")
        say("|---|---:|---:|---:|---|")
        for method, extra in (("tikhonov", []), ("tv", ["--iterations", "30"]), ("drizzle", [])):
            out = os.path.join(work, f"{method}.fits")
            p = subprocess.run([reference, "reconstruct", ds_dir, method, out, "--repeat", str(repeats), *extra],
                               capture_output=True, text=True, check=True)
            import json
            cpp = json.loads(p.stdout)["seconds"]
            options = {"iterations": int(extra[1])} if extra else {}
            best, rec = float("inf"), None
            for _ in range(repeats):
                t0 = time.perf_counter()
                rec = aosr.reconstruct(ds, method, **options)
                best = min(best, time.perf_counter() - t0)
            expected = aosr.read_fits(out)[0]
            same = np.array_equal(rec.image.view(np.uint64), expected.view(np.uint64))
            say(f"| {method}{' (30 it.)' if extra else ''} | {cpp:.4f} | {best:.4f} | {best / cpp:.3f} | {same} |")
        say()

        # ---- 2. 16 datasets on a 2-worker LocalCluster vs serial ----------------------------------------------
        n = 4 if args.quick else 16
        scene = aosr.load_scene(os.path.join(root, "data", "scenes", "paper-sim-r4.json"))
        paths = []
        for k in range(n):
            path = os.path.join(work, f"night-{k:02d}")
            aosr.simulate(scene, seed=1000 + k, output=path)
            paths.append(path)
        method, options = "tv", {"iterations": 40}
        say(f"## 2. {n} datasets (paper-sim-r4 at {n} seeds: {len(ds)} frames, HR "
            f"{scene.hr_shape[0]}x{scene.hr_shape[1]}), method {method} ({options['iterations']} iterations), "
            "FITS written per dataset")
        say()
        say("| run | wall [s] | speed-up vs serial (1 thread) | outputs identical to serial |")
        say("|---|---:|---:|---|")
        t0 = time.perf_counter()
        serial = ad.reconstruct_many(paths, os.path.join(work, "serial"), method, client="serial", threads=1,
                                     dtype="float64", **options)
        t_serial = time.perf_counter() - t0
        say(f"| serial loop, 1 aosr thread per task | {t_serial:.2f} | 1.00 | - |")
        t0 = time.perf_counter()
        serial2 = ad.reconstruct_many(paths, os.path.join(work, "serial2"), method, client="serial", threads=2,
                                      dtype="float64", **options)
        t_serial2 = time.perf_counter() - t0
        same2 = [a["image_sha256"] for a in serial] == [b["image_sha256"] for b in serial2]
        say(f"| serial loop, 2 aosr threads per task | {t_serial2:.2f} | {t_serial / t_serial2:.2f} | {same2} |")
        from dask.distributed import Client, LocalCluster
        t0 = time.perf_counter()
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            t_up = time.perf_counter() - t0
            client.run(lambda: __import__("aosr"))  # workers import aosr once, as a real batch would
            t1 = time.perf_counter()
            dist = ad.reconstruct_many(paths, os.path.join(work, "dask"), method, client=client, threads=1,
                                       dtype="float64", **options)
            t_batch = time.perf_counter() - t1
        t_total = time.perf_counter() - t0
        same = [a["image_sha256"] for a in serial] == [b["image_sha256"] for b in dist]
        say(f"| LocalCluster 2 workers x 1 thread, batch only | {t_batch:.2f} | {t_serial / t_batch:.2f} | {same} |")
        say(f"| LocalCluster 2 workers x 1 thread, incl. start-up ({t_up:.1f} s) | {t_total:.2f} | "
            f"{t_serial / t_total:.2f} | {same} |")
        say()
        load = os.getloadavg()
        say(f"Load average after the run: {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f}.")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if args.out:
        with open(args.out, "w") as f:
            f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
