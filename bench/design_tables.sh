#!/usr/bin/env bash
# Evaluation tables of issue 6: PSNR/SSIM of {classic raster, optimised tip/tilt, Zernike, non-modal (DM
# actuators)} designs x {Drizzle, Tikhonov, TV, MAP} reconstructors on held-out scenes never used in design,
# at N = 4 for r in {2, 4, 8} and at r = 4 for N in {2, 4, 6, 8}, plus a seeing-limited baseline (AO loop
# open, telescope dithers on the classic raster) reconstructed the same ways.
#
#   bench/design_tables.sh [--quick | --smoke] [--tables-only | --only ROW[,ROW]] [--jobs J] [--out FILE]
#
# --quick: N = 4 at r = 2 and 4, two scenes (natural image, USAF); --smoke: N = 4, r = 2, USAF only, with the
# seeing baseline (checks the script end to end in a few minutes; writes to build/bench-tables/smoke.md
# unless --out); --tables-only: rewrite the file from the last run's results.json; --only: re-run those rows
# (raster, tiptilt, zernike, actuators, zernike-B, seeing) into the last run's results and rewrite. Writes bench/results/design_tables.md
# (or FILE); scratch (scenes, designs, datasets, reconstructions, raw JSON) goes to build/bench-tables/.
# Needs build/aosr (cmake --build build -j2 --target aosr_cli) and the held-out images of
# bench/fetch_heldout.sh (run here if build/heldout/ is empty). bash + python3 standard library only.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
quick=0
tables_only=0
only=""
jobs=2
out="bench/results/design_tables.md"
cmdline="bench/design_tables.sh $*"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) quick=1 ;;
    --tables-only) tables_only=1 ;;
    --only) only="$2"; shift ;;
    --smoke) quick=2; out="build/bench-tables/smoke.md" ;;
    --jobs) jobs="$2"; shift ;;
    --out) out="$2"; shift ;;
    -h|--help) sed -n 2,13p "$0"; exit 0 ;;
    *) echo "design_tables: unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done
[[ -x build/aosr ]] || { echo "design_tables: build/aosr missing: cmake --build build -j2 --target aosr_cli" >&2; exit 1; }
if ! ls build/heldout/*.png >/dev/null 2>&1; then bench/fetch_heldout.sh >/dev/null; fi
mkdir -p "$(dirname "$out")"

AOSR_ROOT="$root" QUICK="$quick" TABLES_ONLY="$tables_only" ONLY="$only" JOBS="$jobs" OUT="$out" CMDLINE="$cmdline" python3 - <<'PYEOF'
import concurrent.futures as cf
import datetime, json, math, os, platform, struct, subprocess, sys, time, zlib

ROOT = os.environ["AOSR_ROOT"]
QUICK = os.environ["QUICK"] != "0"
SMOKE = os.environ["QUICK"] == "2"
JOBS = int(os.environ["JOBS"])
OUT = os.environ["OUT"]
AOSR = os.path.join(ROOT, "build", "aosr")
SCRATCH = os.path.join(ROOT, "build", "bench-tables", "smoke" if SMOKE else "quick" if QUICK else "full")
os.makedirs(SCRATCH, exist_ok=True)
T0 = time.time()

# ---------------------------------------------------------------- settings (stated in the tables file)
FRAME_PX = 64                      # camera pixels per side (= 64 lambda/D: 3.6 arcsec at K)
NATURAL = "camera.png"             # held-out natural image (bench/fetch_heldout.sh)
TAPER = 0.15                       # cosine taper to 0 over this fraction of each edge of the natural image
# The design sees the instrument, the noise and the object statistics, never the held-out scenes: objective A
# in its Wiener form, with the power spectrum fitted to two *other* skimage images (moon, coins; camera.png is
# held out) scaled to peak 1, and the noise per LR pixel in those units. The tables' noise is 1 % of the
# brightest noiseless LR pixel, which sums r² HR pixels near the peak: measured sigma_e = 30-34 e- at r = 2 and
# 116-136 e- at r = 4 for a 1000 e-/HR px peak, i.e. sigma ~ 0.008 r² at peak 1.
TRAINING = ["moon.png", "coins.png"]
def noise_sigma(r):
    return 0.008 * r * r
DESIGN_ARGS = ["--starts", "1", "--iterations", "30", "--realisations", "1", "--screens", "2"]
# (row key, label, aosr design arguments, configurations (None: all)). Objective B (the MAP loss, implicit
# gradient) is slower: a 10-iteration Zernike refinement at N = 4, r = 2 and 4 only.
PARAMS = [("raster", "classic raster", ["--param", "raster"], None),
          ("tiptilt", "optimised tip/tilt", ["--param", "tiptilt"], None),
          ("zernike", "Zernike (20 modes)", ["--param", "zernike", "--modes", "20"], None),
          ("actuators", "non-modal (actuators)", ["--param", "actuators"], None),
          ("zernike-B", "Zernike (20 modes), objective B", ["--param", "zernike", "--modes", "20", "--objective", "B",
                                                            "--loss", "l1", "--iterations", "10"], [(4, 2), (4, 4)])]
def design_args(extra, r):
    base = list(DESIGN_ARGS)
    if "--iterations" in extra:  # the row's own iteration cap replaces the default
        k = base.index("--iterations")
        del base[k:k + 2]
    args = base + extra + ["--noise-sigma", repr(noise_sigma(r))]
    if "B" in extra:
        # The MAP that objective B differentiates gets the weights `aosr reconstruct -m map` chooses for these
        # frames: λ = 2μ, μ = 0.5 ρ √w̄ with whitened residuals (ρ ≈ 1, w̄ = 1/σ_e²), i.e. λ = 1/σ in peak-1
        # units, and ε = 1e-3 × the contrast (1 here). B's defaults (λ = 1, ε = 1e-2) are ~30x weaker and
        # designed for a different reconstructor: the first full run's B row, made with them, won on its own
        # loss and lost 0.1-0.4 dB on the held-out scenes.
        args += ["--map-lambda", repr(1.0 / noise_sigma(r)), "--epsilon", "1e-3"]
    return args + ["--training"] + [os.path.join(ROOT, "build", "heldout", t) for t in TRAINING]
METHODS = [("drizzle", "Drizzle", []), ("tikhonov", "Tikhonov (GCV)", []),
           ("tv", "TV", ["--iterations", "100"]), ("map", "MAP", ["--iterations", "100"])]
EVAL_CROP_CAMERA_PX = 4            # border ignored by the metrics, camera px (x r HR px), the same for every row
if SMOKE:
    CONFIGS = [(4, 2)]
    SCENES = ["usaf"]
elif QUICK:
    CONFIGS = [(4, 2), (4, 4)]     # (N, r)
    SCENES = ["natural", "usaf"]
else:
    CONFIGS = [(4, 2), (4, 4), (4, 8), (2, 4), (6, 4), (8, 4)]
    SCENES = ["natural", "usaf", "stars", "galaxies"]
# The seeing-limited baseline needs the zero-padded model (below), whose CG solves are slow on the badly
# conditioned seeing OTF (r = 2: ~80 CPU-s per scene for the discrepancy search; r = 4: over 10 min per scene
# on the loaded machine): it runs at N = 4, r = 2 on the natural image and the USAF target only.
SEEING_CONFIGS = [(4, 2)]
SEEING_SCENES = ["usaf"] if SMOKE else ["natural", "usaf"]
SCENE_LABEL = {"natural": "natural image (skimage camera.png)", "usaf": "USAF 1951 target",
               "stars": "star field", "galaxies": "galaxy field"}

def log(msg):
    print("[%6.0f s] %s" % (time.time() - T0, msg), file=sys.stderr, flush=True)

def run_json(args):
    p = subprocess.run([AOSR] + args + ["--json"], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError("aosr %s failed (%d): %s" % (" ".join(args), p.returncode, p.stderr.strip()[-400:]))
    return json.loads(p.stdout)

# ---------------------------------------------------------------- natural image: PNG -> tapered FITS
def read_png_grey8(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, w = 8, b"", None
    while pos < len(data):
        n, = struct.unpack(">I", data[pos:pos + 4]); kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + n]; pos += 12 + n
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or ctype != 0 or interlace != 0:
                raise ValueError("%s: only 8-bit greyscale non-interlaced PNGs are handled" % path)
        elif kind == b"IDAT":
            idat += body
    raw, rows, prev = zlib.decompress(idat), [], bytearray(w)
    for y in range(h):
        f, line = raw[y * (w + 1)], bytearray(raw[y * (w + 1) + 1:(y + 1) * (w + 1)])
        for x in range(w):
            a = line[x - 1] if x else 0; b = prev[x]; c = prev[x - 1] if x else 0
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c; pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(list(line)); prev = line
    return rows

def write_fits(path, rows):
    h, w = len(rows), len(rows[0])
    cards = ["SIMPLE  = %20s" % "T", "BITPIX  = %20d" % -32, "NAXIS   = %20d" % 2, "NAXIS1  = %20d" % w,
             "NAXIS2  = %20d" % h, "END"]
    head = "".join(c.ljust(80) for c in cards); head += " " * (-len(head) % 2880)
    body = b"".join(struct.pack(">%df" % w, *r) for r in rows); body += b"\0" * (-len(body) % 2880)
    with open(path, "wb") as f:
        f.write(head.encode("ascii") + body)

def tapered_natural():
    """The centred square of the sample image, its edges taken smoothly to 0 (a vignetted field), so that
    no reconstructor is judged on light that a frame edge cut off; written as FITS for the image object."""
    dst = os.path.join(SCRATCH, "natural-tapered.fits")
    rows = read_png_grey8(os.path.join(ROOT, "build", "heldout", NATURAL))
    h, w = len(rows), len(rows[0]); s = min(h, w); y0, x0 = (h - s) // 2, (w - s) // 2
    band = TAPER * s
    def t(i):
        d = min(i + 0.5, s - i - 0.5)
        return 1.0 if d >= band else 0.5 - 0.5 * math.cos(math.pi * d / band)
    wt = [t(i) for i in range(s)]
    write_fits(dst, [[rows[y0 + i][x0 + j] * wt[i] * wt[j] for j in range(s)] for i in range(s)])
    return dst

# ---------------------------------------------------------------- scenes
PAPER_8M = json.load(open(os.path.join(ROOT, "data", "telescopes", "paper-8m.json")))
def open_loop_telescope():
    t = json.loads(json.dumps(PAPER_8M))
    t["name"] = "paper-8m-open-loop"
    t["comment_bench"] = "paper-8m with the AO loop gain 0: the analytic model's open loop, i.e. the seeing-limited long exposure"
    t["ao"]["loop"]["gain"] = 0.0
    return t

DETECTOR = {"frame_px": FRAME_PX, "noise": "peak-fraction", "peak_noise_fraction": 0.01, "saturation": False,
            "comment": "the paper's noise: Gaussian, sigma = 1% of the brightest noiseless pixel"}

def objects(kind, natural_fits):
    if kind == "natural":
        return [{"type": "image", "path": natural_fits, "fit": "crop", "flux": {"peak_e": 1000}}]
    if kind == "usaf":
        return [{"type": "usaf", "fill": 0.7, "first_group": -2, "last_group": 1, "flux": {"peak_e": 1000}}]
    if kind == "stars":
        return [{"type": "stars", "count": 40, "alpha": 2.0, "flux_range_e": [200, 20000], "margin_px": 6}]
    if kind == "galaxies":
        return [{"type": "galaxies", "count": 8, "half_light_radius_px": [0.5, 3], "flux_range_e": [2000, 40000],
                 "margin_px": 8}]
    raise ValueError(kind)

SEED = {"natural": 101, "usaf": 102, "stars": 103, "galaxies": 104}

def scene(name, n, r, kind, natural_fits, offsets, seeing=False):
    s = {"name": name, "seed": SEED.get(kind, 100), "telescope": open_loop_telescope() if seeing else "paper-8m",
         "frames": n, "r": r, "ao": {"mode": "analytic"}, "offsets": offsets,
         "objects": objects(kind, natural_fits), "detector": DETECTOR}
    if seeing:
        s["psf"] = {"window_lambda_over_d": 64,
                    "comment": "seeing halo lambda/r0 ~ 10 lambda/D at K: the default 32 lambda/D window would fold too much light"}
    return s

# ---------------------------------------------------------------- one dataset: simulate, reconstruct, evaluate
# The seeing-limited PSF (FWHM ~10 lambda/D, halo to the 64 lambda/D window) is as wide as the frame, so the
# periodic model is wrong at every pixel (light wraps in the model, leaves the frame in the data): GCV then
# chooses lambda at the bottom of its grid (1e-14) and Tikhonov diverges (-23 dB). Those rows use the
# zero-padded model with the discrepancy principle (GCV needs the periodic Fourier path), and TV and MAP
# take that lambda for their Tikhonov pilot (warm start and automatic weight); their own model stays periodic.
SEEING_TIKHONOV = ["--boundary", "padded", "--lambda-rule", "discrepancy"]

def one_dataset(tag, scene_json, r, seeing=False):
    d = os.path.join(SCRATCH, tag)
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, "scene.json")
    json.dump(scene_json, open(path, "w"), indent=1)
    run_json(["simulate", path, "-o", d])
    res = {}
    pilot = []
    for m, _, extra in METHODS:
        est = os.path.join(d, m + ".fits")
        if seeing and m == "tikhonov":
            extra = extra + SEEING_TIKHONOV
        elif seeing and m in ("tv", "map"):
            extra = extra + pilot
        rec = run_json(["reconstruct", d, "-m", m, "-o", est] + extra)
        if seeing and m == "tikhonov":
            pilot = ["--boundary", "padded", "--lambda", repr(rec["regularisation"])]
        ev = run_json(["evaluate", "--manifest", d, "--estimate", est, "--crop", str(EVAL_CROP_CAMERA_PX * r)])
        res[m] = {"psnr": ev["psnr_db"] if "psnr_db" in ev else ev.get("psnr"),
                  "ssim": ev["ssim"], "seconds": rec.get("seconds_total"),
                  "lambda": rec.get("regularisation"), "message": rec.get("summary", {}).get("message", "")}
        json.dump({"reconstruct": rec, "evaluate": ev}, open(os.path.join(d, m + ".json"), "w"), indent=1)
    return tag, res

ONLY = [k for k in os.environ["ONLY"].split(",") if k]

def load_saved():
    saved = json.load(open(os.path.join(SCRATCH, "results.json")))
    return saved["results"], {tuple(k.split("/", 1)): v for k, v in saved["designs"].items()}

def main():
    natural_fits = tapered_natural()
    results, designs = load_saved() if ONLY else ({}, {})
    pool = cf.ThreadPoolExecutor(max_workers=JOBS)
    futures = []
    for n, r in CONFIGS:
        cfg = "N%d-r%d" % (n, r)
        inst = os.path.join(SCRATCH, cfg, "instrument.json")
        os.makedirs(os.path.dirname(inst), exist_ok=True)
        json.dump(scene("instrument-" + cfg, n, r, "usaf", natural_fits, {"type": "raster"}), open(inst, "w"), indent=1)
        for p, _, extra, only in PARAMS:
            if (only is not None and (n, r) not in only) or (ONLY and p not in ONLY):
                continue
            dfile = os.path.join(SCRATCH, cfg, "design-%s.json" % p)
            t = time.time()
            dj = run_json(["design", inst, "-o", dfile] + design_args(extra, r))
            designs[(cfg, p)] = {k: dj.get(k) for k in ("objective_raster", "objective_start", "objective_final",
                                                       "iterations", "termination", "parameters", "total_seconds",
                                                       "objective", "validation", "object_spectrum")}
            log("%s design %-9s J raster %.4f -> final %.4f (%s, %.0f s)" % (cfg, p, dj["objective_raster"],
                dj["objective_final"], dj.get("termination"), time.time() - t))
            for kind in SCENES:
                sc = scene("%s-%s-%s" % (cfg, p, kind), n, r, kind, natural_fits, {"type": "design", "file": dfile})
                futures.append(pool.submit(one_dataset, "%s/%s/%s" % (cfg, p, kind), sc, r))
        for kind in (SEEING_SCENES if (n, r) in SEEING_CONFIGS and (not ONLY or "seeing" in ONLY) else []):
            sc = scene("%s-seeing-%s" % (cfg, kind), n, r, kind, natural_fits, {"type": "raster"}, seeing=True)
            futures.append(pool.submit(one_dataset, "%s/seeing/%s" % (cfg, kind), sc, r, True))
    for f in cf.as_completed(futures):
        tag, res = f.result()
        results[tag] = res
        log("%-28s %s" % (tag, "  ".join("%s %.2f/%.3f" % (m, v["psnr"], v["ssim"]) for m, v in res.items())))
    pool.shutdown()
    json.dump({"results": results, "designs": {"%s/%s" % k: v for k, v in designs.items()}},
              open(os.path.join(SCRATCH, "results.json"), "w"), indent=1)
    write_tables(results, designs)

# ---------------------------------------------------------------- the Markdown file
ROWS = [(p, label) for p, label, _, _ in PARAMS] + [("seeing", "**seeing-limited baseline** (no AO, raster dithers)")]

def cell(vals):
    return "%.2f / %.3f" % (sum(v[0] for v in vals) / len(vals), sum(v[1] for v in vals) / len(vals))

def table(results, cfg, scenes):
    lines = ["| design | " + " | ".join(label for _, label, _ in METHODS) + " |",
             "|---|" + "---|" * len(METHODS)]
    for p, label in ROWS:
        if any("%s/%s/%s" % (cfg, p, k) not in results for k in scenes):
            continue  # the seeing baseline is not run for every configuration and scene
        cells = []
        for m, _, _ in METHODS:
            vals = [(results["%s/%s/%s" % (cfg, p, k)][m]["psnr"], results["%s/%s/%s" % (cfg, p, k)][m]["ssim"])
                    for k in scenes]
            cells.append(cell(vals))
        lines.append("| %s | %s |" % (label, " | ".join(cells)))
    return lines

def mean_psnr(results, cfg, p, m, scenes=None):
    v = [results["%s/%s/%s" % (cfg, p, k)][m]["psnr"] for k in (scenes or SCENES)]
    return sum(v) / len(v)

def write_tables(results, designs):
    up = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    L = []
    title = "quick run" if QUICK else "full run"
    L += ["## %s" % title, "",
          "Command: `%s` (from the repository root, after `bench/fetch_heldout.sh`)." % (
              os.environ["CMDLINE"].strip() if not ONLY else "bench/design_tables.sh%s`, then `%s" % (
                  " --quick" if QUICK else "", os.environ["CMDLINE"].strip())),
          "", "- date: %s" % datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
          "- machine: %s, %d cores, `uptime` at the end: `%s`; wall time %.0f s with %d parallel jobs" %
          (platform.platform(), os.cpu_count() or 0, up, time.time() - T0, JOBS),
          "- git: `%s`" % subprocess.run(["git", "-C", ROOT, "log", "-1", "--format=%h %s"], capture_output=True,
                                          text=True).stdout.strip()[:100],
          "- configurations (N, r): %s" % ", ".join("(%d, %d)" % c for c in CONFIGS),
          "- held-out scenes (never seen by `aosr design`, which only sees the instrument): %s" %
          ", ".join(SCENE_LABEL[k] for k in SCENES), ""]
    L += ["### Settings", "",
          "- instrument: the `paper-8m` preset of `data/scenes/paper-sim-r2.json` (8 m, K-band camera pixel = λ/D, "
          "17×17 DM, 16×16 SH, 800 Hz), `\"ao\": {\"mode\": \"analytic\"}` (long-exposure analytic AO PSF; the "
          "reconstructors are given the exact simulated PSFs), %d × %d camera px frames, the paper's noise (Gaussian, "
          "σ = 1 %% of the brightest noiseless pixel), r and N per configuration." % (FRAME_PX, FRAME_PX),
          "- design: `aosr design <instrument scene> --param P %s --training moon.png coins.png --noise-sigma "
          "0.008·r²` with `--modes 20` for Zernike (objective A, Wiener form: the object power spectrum fitted to "
          "skimage's moon and coins images at peak 1 — never the held-out camera.png — and the noise per LR pixel "
          "in those units, 1 %% of a peak LR pixel of r² HR pixels); the design is then re-judged against the "
          "raster on 4 fresh AO realisations and the raster kept unless the design wins there (`validation` "
          "below). Objective-B row (N = 4, r = 2 and 4): `--objective B --loss l1 --iterations 10 --map-lambda "
          "1/σ --epsilon 1e-3` (the weights `aosr reconstruct -m map` chooses for such frames) with the same "
          "training images as scenes. The instrument scene holds a USAF object only because a scene needs one "
          "(the design ignores objects)." % " ".join(DESIGN_ARGS),
          "- reconstruction: `aosr reconstruct DATASET -m M` with defaults (inverse-variance weights, Tikhonov λ by "
          "GCV with the gradient prior, periodic boundary; TV and MAP weights automatic) and `--iterations 100` for "
          "TV and MAP; metrics by `aosr evaluate --manifest DATASET --estimate EST --crop %d·r` (the same %d camera px "
          "border ignored in every row; PSNR with L = max − min of the truth)." % (EVAL_CROP_CAMERA_PX, EVAL_CROP_CAMERA_PX),
          "- scenes (seeds fixed per scene, so every row of a configuration sees the same sky and the same noise seed): "
          "natural image: the centred square of skimage's `camera.png` (cameraman, 512², Debian `python3-skimage`), "
          "its edges cosine-tapered to 0 over %d %% of the side (so periodic-boundary reconstructors are not judged on "
          "light a frame edge cut off), peak 1000 e⁻/HR px; USAF: groups −2..1 filling 70 %% of the frame; star "
          "field: 40 stars, dN/dF ∝ F⁻², 200–20000 e⁻, 6 px margin; galaxy field: 8 Sérsic galaxies, "
          "half-light radius 0.5–3 camera px, 2000–40000 e⁻, 8 px margin." % int(TAPER * 100),
          "- seeing-limited baseline (%s; natural image and USAF only; its gain column compares on those scenes): the same scenes through `paper-8m` with the AO loop gain set to 0 (an inline "
          "telescope preset; the analytic model with g = 0 is the open loop: the whole von Kármán phase PSD, no "
          "correction, no WFS noise or aliasing, i.e. the seeing-limited long-exposure PSF, r0 = 15 cm at 550 nm ≈ "
          "0.8 m at K, FWHM ≈ 10 λ/D), PSF window 64 λ/D, dithered by pure image shifts on the classic raster (a "
          "telescope dither moves the image exactly as tip/tilt does), reconstructed the same four ways except "
          "for the boundary: the seeing PSF is as wide as the frame, so the periodic model is wrong everywhere (with it "
          "GCV picks λ ≈ 1e-14 and Tikhonov diverges to −23 dB); Tikhonov runs `--boundary padded --lambda-rule "
          "discrepancy` and TV and MAP take that λ for their pilot (`--boundary padded --lambda λ`)."
          % ", ".join("N = %d, r = %d" % c for c in SEEING_CONFIGS), ""]
    L += ["### Design objective J (`aosr design --json`: A = expected Wiener MSE per HR pixel, B = mean L1 loss "
          "of the MAP reconstruction; peak-1 units)", "",
          "| N, r | design | J raster | J start | J final | change | iterations | termination | parameters | "
          "validation (J raster / J design on fresh realisations: kept) | s |",
          "|---|---|---|---|---|---|---|---|---|---|---|"]
    for n, r in CONFIGS:
        cfg = "N%d-r%d" % (n, r)
        for p, label, _, _ in PARAMS:
            if (cfg, p) not in designs:
                continue
            d = designs[(cfg, p)]
            v = d.get("validation")
            val = "%.6g / %.6g: %s" % (v["objective_raster"], v["objective_design"], v["kept"]) if v else "—"
            L.append("| %d, %d | %s | %.6g | %.6g | %.6g | %+.3f %% | %s | %s | %s | %s | %.0f |" % (
                n, r, label, d["objective_raster"], d["objective_start"], d["objective_final"],
                100 * (d["objective_final"] / d["objective_raster"] - 1), d["iterations"],
                d["termination"], d["parameters"], val, d["total_seconds"] or 0))
    spectra = [d["object_spectrum"] for d in designs.values() if d.get("object_spectrum")]
    if spectra:
        sp = spectra[0]
        L += ["", "Fitted object spectrum (A's Wiener prior, per grid; first design): a = %.3g, f0 = %.3g cycles/HR px, "
              "β = %.2f, log residual %.3f over %d patches." % (sp["amplitude"], sp["corner"], sp["slope"],
                                                               sp["residual_rms"], sp["patches"])]
    L += [""]
    L += ["### PSNR [dB] / SSIM, mean over the held-out scenes", ""]
    for n, r in CONFIGS:
        cfg = "N%d-r%d" % (n, r)
        L += ["#### N = %d, r = %d" % (n, r), ""] + table(results, cfg, SCENES) + [""]
    L += ["### Gains over the classic raster (mean PSNR difference, dB) and over the seeing-limited baseline", "",
          "| N, r | method | tip/tilt − raster | Zernike − raster | non-modal − raster | Zernike B − raster | best AO − seeing |",
          "|---|---|---|---|---|---|---|"]
    for n, r in CONFIGS:
        cfg = "N%d-r%d" % (n, r)
        for m, label, _ in METHODS:
            base = mean_psnr(results, cfg, "raster", m)
            if (n, r) in SEEING_CONFIGS:  # over the scenes the baseline saw
                best = max(mean_psnr(results, cfg, p, m, SEEING_SCENES) for p, _, _, _ in PARAMS
                           if (cfg, p) in designs)
                seeing = "%+.2f" % (best - mean_psnr(results, cfg, "seeing", m, SEEING_SCENES))
            else:
                seeing = "—"
            zb = ("%+.2f" % (mean_psnr(results, cfg, "zernike-B", m) - base)) if (cfg, "zernike-B") in designs else "—"
            L.append("| %d, %d | %s | %+.2f | %+.2f | %+.2f | %s | %s |" % (
                n, r, label, mean_psnr(results, cfg, "tiptilt", m) - base, mean_psnr(results, cfg, "zernike", m) - base,
                mean_psnr(results, cfg, "actuators", m) - base, zb, seeing))
    L += ["", "### Per-scene PSNR [dB] / SSIM", ""]
    for n, r in CONFIGS:
        cfg = "N%d-r%d" % (n, r)
        for k in SCENES:
            L += ["#### N = %d, r = %d: %s" % (n, r, SCENE_LABEL[k]), ""] + table(results, cfg, [k]) + [""]
    L += ["<!-- what-the-numbers-say:%s -->" % title, ""]
    section = "\n".join(L) + "\n"
    # Keep the other run's section if the file already has one (quick and full are labelled).
    other = ""
    if os.path.exists(OUT):
        text = open(OUT).read()
        mine, theirs = ("## quick run", "## full run") if QUICK else ("## full run", "## quick run")
        if theirs in text:
            start = text.index(theirs)
            end = text.index(mine, start) if mine in text[start:] else len(text)
            other = text[start:end].rstrip() + "\n"
    head = ("# Design tables (issue 6)\n\nGenerated by `bench/design_tables.sh` (the held-out images by "
            "`bench/fetch_heldout.sh`). Each section states the command that made it. The paper's linear-method "
            "PSNRs come from other images and noise: compare gains between rows, not absolute values.\n\n")
    sections = [section, other] if not QUICK else [other, section]
    open(OUT, "w").write(head + "\n".join(s for s in sections if s))
    log("wrote %s" % OUT)

if os.environ["TABLES_ONLY"] == "1":  # rewrite the Markdown from the last run's results.json
    write_tables(*load_saved())
else:
    main()
PYEOF
