"""aosr: super-resolved imaging with adaptive optics, from Python.

Bindings of the C++ library (not of the CLI): every function here makes the library call the matching
``aosr`` command makes, with the same defaults, and returns the same numbers bit for bit.

    >>> import aosr
    >>> ds = aosr.simulate(aosr.load_scene("data/scenes/demo.json"), seed=1)
    >>> rec = aosr.reconstruct(ds, "tv")
    >>> aosr.evaluate(rec.image, dataset=ds)["psnr_db"]

Arrays are (rows, cols) = (y, x) float64; stacks are (N, rows, cols). Results the library computes are
handed over without copies (the array's ``.base`` keeps the C++ object alive); inputs are copied once into
the library's images (a plain memcpy for C-contiguous float64 arrays). Long calls release the GIL; Ctrl-C
stops tv/map after the current iteration and raises KeyboardInterrupt. aosr uses every hardware thread
(as the CLI; ``set_threads`` changes it; results are the same bytes for any count). Errors are ``aosr.Error``
subclasses that are also the builtin you would catch: ``InvalidArgument`` (ValueError), ``IoError``
(OSError), ``ResourceError`` (MemoryError), ``NumericalError`` (ArithmeticError).

Scale-out over Dask: :mod:`aosr.distributed`. The whole API: docs/python.md.
"""

import copy as _copy
import os as _os

from . import _aosr
from ._aosr import (  # noqa: F401  (re-exported API)
    CalibrationSet,
    Dataset,
    Error,
    InvalidArgument,
    IoError,
    NumericalError,
    Reconstruction,
    ResourceError,
    Scene,
    __version__,
    calibrate,
    compare_images,
    compare_images_aligned,
    compare_mtf,
    compare_images_rings,
    design,
    evaluate,
    fourier_shift,
    methods,
    mtf,
    open_dataset,
    psf,
    psnr,
    read_fits,
    read_json,
    reconstruct,
    reconstruct_options,
    set_fft_planner,
    fft_wisdom_loaded,
    allocator_tuned,
    bicubic,
    tune_allocator,
    set_memory_limit,
    set_threads,
    simulate,
    stars_psf,
    synthesize_calibration,
    tradeoff,
    threads,
    usaf_resolving_power,
    video,
    VideoStream,
    watch,
    QuickLook,
    write_figure,
    write_fits,
    write_image,
)

__all__ = [
    "CalibrationSet", "Dataset", "bicubic", "Error", "InvalidArgument", "IoError", "NumericalError", "Reconstruction",
    "ResourceError", "Scene", "calibrate", "compare_images", "compare_images_aligned", "compare_images_rings", "compare_mtf", "data_path", "design",
    "evaluate", "fourier_shift", "load_scene",
    "methods", "mtf", "open_dataset", "psf", "psnr", "read_fits", "read_json", "reconstruct", "reconstruct_options",
    "scene_from_dict", "set_fft_planner", "fft_wisdom_loaded", "allocator_tuned", "tune_allocator", "set_memory_limit", "set_threads", "simulate", "stars_psf",
    "synthesize_calibration", "threads", "tradeoff", "usaf_resolving_power", "video", "VideoStream", "watch", "QuickLook", "write_figure", "write_fits", "write_image",
]


def _apply_override(json, key, value):
    """Sets one dotted field of a scene's JSON, as the CLI's ``--set KEY=VALUE`` (a numeric part indexes a list)."""
    parts = key.split(".")
    if not key or any(p == "" for p in parts):
        raise InvalidArgument(f"aosr.load_scene: invalid override key {key!r}; allowed: a dotted field path, e.g. "
                              "'r' or 'detector.noise'")
    node = json
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            try:
                index = int(part)
                if last:
                    node[index] = value
                else:
                    node = node[index]
                continue
            except (ValueError, IndexError):
                raise InvalidArgument(f"aosr.load_scene: invalid override key {key!r}; allowed: an index of the "
                                      f"list at {'.'.join(parts[:i]) or '(top)'}") from None
        if not isinstance(node, dict):
            raise InvalidArgument(f"aosr.load_scene: invalid override key {key!r}; allowed: a path through objects")
        if last:
            node[part] = value
        else:
            node = node.setdefault(part, {})


def load_scene(path, overrides=None):
    """Reads and validates a scene file (data/scenes/README.md) and returns an :class:`aosr.Scene`.

    ``overrides`` is a dict of dotted field paths to values applied to the JSON before parsing, as the CLI's
    ``aosr simulate --set KEY=VALUE`` (e.g. ``{"r": 4, "detector.noise": "none", "objects.0.flux.peak_e": 50}``).
    Errors name the file and the field.
    """
    path = _os.fspath(path)
    if not overrides:
        return Scene.load(path)
    json = read_json(path)
    for key, value in overrides.items():
        _apply_override(json, key, value)
    return Scene(json, path)


def scene_from_dict(json, source="<dict>", overrides=None):
    """An :class:`aosr.Scene` from a dict of the scene file's JSON (``overrides`` as in :func:`load_scene`)."""
    json = _copy.deepcopy(json)
    for key, value in (overrides or {}).items():
        _apply_override(json, key, value)
    return Scene(json, source)


# An installed package (pip install .) ships its own copy of data/; the library's presets by name use it too.
# Run from a build folder (PYTHONPATH=build/python) the package has none and the source tree's data/ is used.
_PACKAGE_DATA = _os.path.join(_os.path.dirname(_os.path.abspath(__file__)), "data")
if _os.path.isdir(_os.path.join(_PACKAGE_DATA, "telescopes")):
    _aosr._set_default_data_dir(_PACKAGE_DATA)
    _DATA_DIR = _PACKAGE_DATA
else:
    _DATA_DIR = _aosr._data_dir


def data_path(*parts):
    """A path inside aosr's data/ folder (scenes, telescopes, calibration specs), e.g.
    ``aosr.data_path("scenes", "demo.json")``: the installed package's copy, or the source tree's data/ when the
    package runs from a build folder. Set AOSR_DATA_DIR to use another data folder."""
    root = _os.environ.get("AOSR_DATA_DIR") or _DATA_DIR
    return _os.path.join(root, *parts)
