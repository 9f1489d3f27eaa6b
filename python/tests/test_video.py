"""aosr.video: the streaming engine as an iterator. Every output equals the batch aosr.reconstruct of its window
(built independently with Dataset.from_arrays from the window's frames in time order) to 1e-10 of the peak, for
Tikhonov (fixed lambda, and lambda chosen once by GCV) and the target-PSF output, sliding and cycle windows;
the times; and argument errors raised when aosr.video is called, before any frame is read."""
import json

import numpy as np
import pytest

import aosr

R = 2
HR = (48, 40)
SHIFTS = [(0, 0), (0, 1), (1, 0), (1, 1.5)]  # HR px, one per phase
FRAMES = 10
DT = 0.05
GAIN, BIAS = 2.0, 100.0


def _psfs():
    y, x = np.mgrid[0:16, 0:16]
    out = []
    for dy, dx in SHIFTS:
        k = np.exp(-((y - 8 - dy) ** 2 + (x - 8 - dx) ** 2) / (2 * 1.1 ** 2))
        out.append(k / k.sum())
    return np.array(out)


def _render(x, psf):
    """One phase's frame of HR object x: periodic convolution with the centred PSF, then r x r pixel sums."""
    k = np.zeros(HR)
    h = psf.shape[0] // 2
    k[:psf.shape[0], :psf.shape[1]] = psf
    k = np.roll(k, (-h, -h), axis=(0, 1))
    blurred = np.fft.irfft2(np.fft.rfft2(x) * np.fft.rfft2(k), s=HR)
    return blurred.reshape(HR[0] // R, R, HR[1] // R, R).sum(axis=(1, 3))


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    """A 10-frame sequence cycling through 4 phases (a blob moving one HR px per frame) as a dataset on disk."""
    d = tmp_path_factory.mktemp("video_seq")
    rng = np.random.default_rng(34)
    psfs = _psfs()
    background = 0.1 * rng.random(HR)
    yy, xx = np.mgrid[0:HR[0], 0:HR[1]]
    frames = []
    for j in range(FRAMES):
        x = background + 3.0 * np.exp(-((yy - 20.0) ** 2 + (xx - 10.0 - j) ** 2) / 8.0)
        e = _render(x, psfs[j % 4]) + 0.01 * rng.standard_normal((HR[0] // R, HR[1] // R))
        frames.append(e / GAIN + BIAS)
    frames = np.array(frames)
    aosr.write_fits(d / "frames.fits", frames, dtype="float64")
    aosr.write_fits(d / "psfs.fits", psfs, dtype="float64")
    manifest = {"format": "aosr-manifest", "version": 1, "frames": "frames.fits", "psfs": "psfs.fits", "r": R,
                "gain_e_per_adu": GAIN, "bias_adu": BIAS,
                "sequence": {"slots": [j % 4 for j in range(FRAMES)], "times_s": [DT * j for j in range(FRAMES)]}}
    (d / "manifest.json").write_text(json.dumps(manifest))
    return d, frames, psfs


def _batch(frames, psfs, window, method, **options):
    """aosr.reconstruct of frames `window` (time order), each with its phase's PSF, as an ordinary dataset."""
    idx = sorted(window)
    ds = aosr.Dataset.from_arrays(frames[idx], psfs[[i % 4 for i in idx]], r=R, gain=GAIN, bias=BIAS)
    return aosr.reconstruct(ds, method, weights="mask", **options).image


def _dev(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


@pytest.mark.parametrize("method,window,options,count", [
    ("tikhonov", "sliding", {"lambda_": 3e-3}, FRAMES - 3),
    ("linear", "sliding", {}, FRAMES - 3),
    ("tikhonov", "cycle", {"lambda_": 1e-2}, FRAMES // 4),
    ("linear", "cycle", {"target_psf": 3.0}, FRAMES // 4),
])
def test_outputs_equal_the_batch_of_each_window(sequence, method, window, options, count):
    d, frames, psfs = sequence
    stream = aosr.video(d, method, window, weights="mask", info=True, **options)
    assert isinstance(stream, aosr.VideoStream)
    outputs = list(stream)
    assert len(outputs) == count
    assert stream.frames_read == FRAMES and stream.frames_total == FRAMES and stream.phases == 4
    for t, image, info in outputs:
        assert image.shape == HR and image.dtype == np.float64
        assert info["path"] == "slot-filter"
        assert t == pytest.approx(DT * max(info["frames"]), abs=1e-12)
        assert info["window_start_s"] == pytest.approx(DT * min(info["frames"]), abs=1e-12)
        assert sorted(j % 4 for j in info["frames"]) == [0, 1, 2, 3]
        if window == "cycle":
            assert sorted(info["frames"]) == list(range(4 * info["index"], 4 * info["index"] + 4))
        ref = _batch(frames, psfs, info["frames"], method, **options)
        assert _dev(image, ref) < 1e-10, (info["index"], _dev(image, ref))
    # The blob moves: the outputs differ (a constant stream would pass the comparison trivially otherwise).
    assert _dev(outputs[1][1], outputs[0][1]) > 0.05


def test_lambda_chosen_once_by_gcv_then_fixed(sequence):
    d, frames, psfs = sequence
    stream = aosr.video(d, "tikhonov", weights="mask", info=True)
    assert stream.setup["lambda_unweighted"] is None
    outputs = list(stream)
    lam = stream.setup["lambda_unweighted"]
    assert lam > 0
    assert stream.setup["batch_outputs"] == 1 and stream.setup["filter_outputs"] == FRAMES - 4
    for t, image, info in outputs:
        if info["index"] == 0:
            assert info["path"] == "batch"
            ref = _batch(frames, psfs, info["frames"], "tikhonov")  # GCV, as the batch chooses it
        else:
            assert info["path"] == "slot-filter"
            ref = _batch(frames, psfs, info["frames"], "tikhonov", lambda_=lam)  # unit weights: lambda = lambda'
        assert _dev(image, ref) < 1e-10, info["index"]


def test_two_tuples_limit_and_exhaustion(sequence):
    d, _, _ = sequence
    stream = aosr.video(str(d / "manifest.json"), "linear", limit=3)
    got = list(stream)
    assert len(got) == 3 and all(len(o) == 2 for o in got)
    assert [t for t, _ in got] == pytest.approx([DT * 3, DT * 4, DT * 5])
    with pytest.raises(StopIteration):
        next(stream)
    assert "3 outputs" in repr(stream)
    # The images are the caller's: writable float64 arrays that outlive the stream.
    del stream
    assert got[0][1].flags.writeable and np.isfinite(got[0][1]).all()


def test_an_ordinary_dataset_is_one_cycle_and_frame_rate_sets_times(sequence):
    _, frames, psfs = sequence
    ds = aosr.Dataset.from_arrays(frames[:4], psfs, r=R, gain=GAIN, bias=BIAS)
    out = list(aosr.video(ds, "linear", weights="mask", frame_rate=20.0))
    assert len(out) == 1
    assert out[0][0] == pytest.approx(3 / 20.0)
    assert _dev(out[0][1], aosr.reconstruct(ds, "linear", weights="mask").image) < 1e-10


@pytest.mark.parametrize("kwargs,error,needle", [
    ({"method": "drizzle"}, aosr.InvalidArgument, "tikhonov | linear | tv"),
    ({"method": "bogus"}, aosr.InvalidArgument, "bogus"),
    ({"window": "sometimes"}, aosr.InvalidArgument, "sliding | cycle"),
    ({"lambda_rule": "wiener"}, aosr.InvalidArgument, "lambda_rule"),
    ({"std": True}, aosr.InvalidArgument, "compute_std"),
    ({"no_such_option": 1}, aosr.InvalidArgument, "no_such_option"),
    ({"limit": -1}, aosr.InvalidArgument, "limit"),
    ({"tv_iterations": 0, "method": "tv"}, aosr.InvalidArgument, "tv_iterations"),
    ({"weights": "everything"}, aosr.InvalidArgument, "weights"),
    ({"model_psfs": "stars"}, aosr.InvalidArgument, "model_psfs"),
    ({"model_psfs": np.ones((3, 16, 16))}, aosr.InvalidArgument, "model_psfs"),
])
def test_bad_arguments_raise_when_called(sequence, kwargs, error, needle):
    d, _, _ = sequence
    kwargs = dict(kwargs)
    method = kwargs.pop("method", "tikhonov")
    with pytest.raises(error, match=needle.replace("|", r"\|")):
        aosr.video(d, method, **kwargs)


def test_bad_datasets_raise_when_called(sequence, tmp_path):
    _, frames, psfs = sequence
    with pytest.raises(aosr.IoError):
        aosr.video(tmp_path / "no_such_dataset")
    with pytest.raises(aosr.InvalidArgument, match="dataset"):
        aosr.video(42)
    ds = aosr.Dataset.from_arrays(frames[:4], psfs, r=R, gain=GAIN, bias=BIAS)
    with pytest.raises(aosr.InvalidArgument, match="frame_rate"):
        aosr.video(ds, frame_rate=0.0)  # the dataset has no times
