"""aosr.watch: the live quick-look as an iterator, fed by a separate writer process (astropy, which writes each
file in place: the half-written case) at 50 frames per second. Every file gives one 'used' event, the outputs equal
aosr.video's over a dataset of the same frames to 1e-10 of the peak, the quick-look files are written, and bad
arguments are refused when aosr.watch is called."""
import json
import subprocess
import sys

import numpy as np
import pytest

import aosr

R = 2
HR = (48, 40)
SHIFTS = [(0, 0), (0, 1), (1, 0), (1, 1.5)]  # HR px, one per phase
GAIN, BIAS = 2.0, 100.0
FRAMES = 16

# The camera: writes frames[j] to DIR/frame_<j>.fits with DMPHASE = j % 4 and TSEC = j / rate, at `rate` per second,
# with astropy (in place, no rename).
WRITER = r"""
import sys, time
import numpy as np
from astropy.io import fits
folder, npy, rate = sys.argv[1], sys.argv[2], float(sys.argv[3])
frames = np.load(npy)
t0 = time.monotonic()
for j, f in enumerate(frames):
    h = fits.Header()
    h["DMPHASE"] = j % 4
    h["TSEC"] = j / rate
    fits.writeto(f"{folder}/frame_{j:04d}.fits", f, h)
    time.sleep(max(0.0, t0 + (j + 1) / rate - time.monotonic()))
"""


def _psfs():
    y, x = np.mgrid[0:16, 0:16]
    out = []
    for dy, dx in SHIFTS:
        k = np.exp(-((y - 8 - dy) ** 2 + (x - 8 - dx) ** 2) / (2 * 1.1 ** 2))
        out.append(k / k.sum())
    return np.array(out)


def _frames(n):
    """ADU frames of a blob moving one HR px per frame, phase j % 4 (periodic convolution, r x r pixel sums)."""
    rng = np.random.default_rng(35)
    psfs = _psfs()
    background = 0.1 * rng.random(HR)
    yy, xx = np.mgrid[0:HR[0], 0:HR[1]]
    out = []
    for j in range(n):
        x = background + 3.0 * np.exp(-((yy - 20.0) ** 2 + (xx - 10.0 - j) ** 2) / 8.0)
        k = np.zeros(HR)
        k[:16, :16] = psfs[j % 4]
        k = np.roll(k, (-8, -8), axis=(0, 1))
        blurred = np.fft.irfft2(np.fft.rfft2(x) * np.fft.rfft2(k), s=HR)
        e = blurred.reshape(HR[0] // R, R, HR[1] // R, R).sum(axis=(1, 3)) + 0.01 * rng.standard_normal(
            (HR[0] // R, HR[1] // R))
        out.append(e / GAIN + BIAS)
    return np.array(out)


def _dataset(folder, frames, sequence):
    folder.mkdir()
    aosr.write_fits(folder / "frames.fits", frames, dtype="float64")
    aosr.write_fits(folder / "psfs.fits", _psfs(), dtype="float64")
    m = {"format": "aosr-manifest", "version": 1, "frames": "frames.fits", "psfs": "psfs.fits", "r": R,
         "gain_e_per_adu": GAIN, "bias_adu": BIAS, "noise": {"model": "peak-fraction", "sigma_e": 0.01}}
    if sequence:
        m["sequence"] = {"slots": [j % 4 for j in range(len(frames))]}
    (folder / "manifest.json").write_text(json.dumps(m))
    return folder


def test_watch_follows_a_writer_process_at_50_frames_per_second(tmp_path):
    pytest.importorskip("astropy")
    frames = _frames(FRAMES)
    model = _dataset(tmp_path / "model", frames[:4], False)
    camera = tmp_path / "camera"
    camera.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    np.save(tmp_path / "frames.npy", frames)
    ql = aosr.watch(camera, model, lambda_=3e-3, time_key="TSEC", output=out, max_files=FRAMES, idle_timeout=30,
                    poll_interval=0.1)
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(camera), str(tmp_path / "frames.npy"), "50"])
    events = list(ql)
    assert writer.wait(timeout=60) == 0
    assert len(events) == FRAMES
    assert [e["status"] for e in events] == ["used"] * FRAMES, [e["message"] for e in events]
    assert sorted(e["phase"] for e in events) == sorted(j % 4 for j in range(FRAMES))
    outputs = [e for e in events if e["image"] is not None]
    assert len(outputs) == FRAMES - 3 and ql.outputs == FRAMES - 3 and ql.used == FRAMES
    written = [e for e in events if e["written_output"] is not None]
    assert len(written) + ql.superseded == len(outputs) and written[-1]["written_output"] == len(outputs) - 1
    assert all(e["latency_s"] > 0 for e in written)
    # The same frames as a sequence dataset, through aosr.video: the same engine, the same outputs.
    seq = _dataset(tmp_path / "seq", frames, True)
    by_time = sorted(events, key=lambda e: e["time_s"])
    assert [round(e["time_s"] * 50) for e in by_time] == list(range(FRAMES))
    reference = [image for _, image in aosr.video(seq, lambda_=3e-3)]
    assert len(reference) == len(outputs)
    # Files reach the watcher in the order written (50 per second), so outputs come in time order.
    for ref, e in zip(reference, outputs):
        assert np.abs(e["image"] - ref).max() <= 1e-10 * np.abs(ref).max()
    last = aosr.read_fits(out / "quicklook.fits")
    image = last[0] if isinstance(last, tuple) else last
    assert np.allclose(np.asarray(image, dtype=float).squeeze(), outputs[-1]["image"], rtol=0,
                       atol=1e-6 * np.abs(outputs[-1]["image"]).max())
    assert (out / "quicklook.png").stat().st_size > 0


def test_watch_refuses_bad_arguments_when_called(tmp_path):
    model = _dataset(tmp_path / "model", _frames(4), False)
    camera = tmp_path / "camera"
    camera.mkdir()
    with pytest.raises(aosr.InvalidArgument, match="phase_key"):
        aosr.watch(camera, model, phase_key="dm phase")
    with pytest.raises(aosr.InvalidArgument, match="max_files"):
        aosr.watch(camera, model, max_files=-1)
    with pytest.raises(aosr.InvalidArgument, match="window"):
        aosr.watch(camera, model, window="rolling")
    with pytest.raises(aosr.IoError, match="nowhere"):
        aosr.watch(tmp_path / "nowhere", model)
    with pytest.raises(aosr.IoError, match="absent"):
        aosr.watch(camera, model, output=tmp_path / "absent")
    # Nothing arrives: the idle limit ends the iteration.
    assert list(aosr.watch(camera, model, idle_timeout=0.3)) == []


def _read_png_gray8(path):
    """A minimal decoder of an 8-bit grayscale PNG (zlib from the standard library; PNG spec, filters 0-4)."""
    import struct
    import zlib
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat = 8, b""
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour = struct.unpack(">IIBB", body[:10])
            assert (depth, colour) == (8, 0), (depth, colour)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = zlib.decompress(idat)
    out = np.zeros((h, w), dtype=np.int64)
    prev = np.zeros(w, dtype=np.int64)
    for y in range(h):
        f, row = raw[y * (w + 1)], np.frombuffer(raw[y * (w + 1) + 1:(y + 1) * (w + 1)], dtype=np.uint8).astype(np.int64)
        cur = np.zeros(w, dtype=np.int64)
        for x in range(w):
            a = cur[x - 1] if x else 0
            b, c = prev[x], (prev[x - 1] if x else 0)
            if f == 0:
                pred = 0
            elif f == 1:
                pred = a
            elif f == 2:
                pred = b
            elif f == 3:
                pred = (a + b) // 2
            else:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[x] = (row[x] + pred) % 256
        out[y], prev = cur, cur
    return out


def test_write_image_maps_the_stretch_to_8_bits_with_row_0_at_the_top(tmp_path):
    ramp = np.add.outer(np.arange(6.0), np.arange(10.0) * 10)  # rows 0..5 (top to bottom), columns 0..90
    aosr.write_image(tmp_path / "ramp.png", ramp, stretch="linear", low=0, high=100)
    got = _read_png_gray8(tmp_path / "ramp.png")
    expected = np.floor((ramp - ramp.min()) / (ramp.max() - ramp.min()) * 255 + 0.5)
    assert got.shape == ramp.shape and np.array_equal(got, expected)
    aosr.write_image(tmp_path / "asinh.png", ramp)  # the quick-look's defaults
    a = _read_png_gray8(tmp_path / "asinh.png")
    assert a[0, 0] == 0 and a[-1, -1] == 255 and np.all(np.diff(a[0]) >= 0)
    with pytest.raises(aosr.InvalidArgument, match="stretch"):
        aosr.write_image(tmp_path / "x.png", ramp, stretch="gamma")
    with pytest.raises(aosr.InvalidArgument, match="percentile"):
        aosr.write_image(tmp_path / "x.png", ramp, low=50, high=10)
    with pytest.raises(aosr.InvalidArgument, match=".jpg"):
        aosr.write_image(tmp_path / "x.jpg", ramp)
