"""hnnstereo: stereo matching with a Hopfield network on OpenCL, from Python.

    import cv2, hnnstereo
    left = cv2.imread("im2.png")            # grey uint8 or BGR, as cv2 gives them
    right = cv2.imread("im6.png")
    result = hnnstereo.match(left, right, max_disparity=64)   # a rectified pair
    result.matches   # float32 N x 6: xl, yl, xr, yr, activation, confidence
    result.report    # dict, the keys of `hnnstereo match --report`

The settings are the CLI's: a preset (``preset="hnn-default"``) and keyword overrides named like
the ``hnnstereo match`` flags (``max_features=1500``, ``top_k=8``, ``no_lr_check=True``...).
Bad input raises ValueError, a failed match RuntimeError, each with the CLI's one-line reason.
The GIL is released while matching. A Matcher (and the one ``match`` keeps per setting) serves one
thread at a time; ``match`` serialises calls that share one.
"""

import json as _json
import os as _os
import threading as _threading

from ._hnnstereo import Calibration, __version__, load_calibration as _load_calibration
from ._hnnstereo import _Matcher, option_names, preset_names, sense_positions as _sense_positions

__all__ = ["Calibration", "MatchResult", "Matcher", "load_calibration", "match", "pick",
           "option_names", "preset_names", "__version__"]


def _option_text(name, value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float, str)):
        return repr(value) if isinstance(value, float) else str(value)
    if isinstance(value, (tuple, list)) and len(value) == 2:  # zrange=(zmin, zmax)
        return ",".join(_option_text(name, v) for v in value)
    raise ValueError(f"option {name!r} needs a number, a string or a flag (got {value!r})")


def _overrides(options):
    return {name.replace("_", "-"): _option_text(name, value) for name, value in options.items()}


def load_calibration(path):
    """Reads a CAL.yml (OpenCV FileStorage) or a Middlebury calib.txt -> Calibration."""
    return _load_calibration(_os.fspath(path))


def _calibration(calib):
    if isinstance(calib, Calibration):
        return calib
    if isinstance(calib, (str, bytes, _os.PathLike)):
        return load_calibration(calib)
    raise ValueError(f"calib must be a path or a hnnstereo.Calibration (got {type(calib).__name__})")


class MatchResult:
    """The matches (float32 N x 6: xl, yl, xr, yr, activation, confidence) and the report."""

    __slots__ = ("matches", "report")

    def __init__(self, matches, report):
        self.matches = matches
        self.report = report

    def __len__(self):
        return len(self.matches)

    def __repr__(self):
        return (f"<hnnstereo.MatchResult {len(self.matches)} matches, engine "
                f"{self.report.get('engine')}, {self.report.get('timing_ms', {}).get('total', 0):.1f} ms>")


def _image(image, name):
    """The image as a numpy array, or a one-line ValueError (never the other image's pixels)."""
    if image is None:
        raise ValueError(f"the {name} image is None (cv2.imread returns None for a path it "
                         "cannot read)")
    if not hasattr(image, "__array_interface__"):
        raise ValueError(f"the {name} image must be a numpy array, not {type(image).__name__}")
    return image


class Matcher:
    """A preset plus overrides, with its OpenCL device opened once. One thread at a time."""

    def __init__(self, preset="hnn-default", engine=None, **options):
        overrides = _overrides(options)
        if engine is not None:  # else the library's default engine (opencl, falling back to cpu)
            overrides["engine"] = str(engine)
        self._matcher = _Matcher(str(preset), overrides)
        self._lock = _threading.Lock()

    @property
    def device(self):
        return self._matcher.device

    @property
    def notice(self):
        return self._matcher.notice

    def match(self, left, right, *, max_disparity=64, calib=None):
        """Rectified pair (calib None: disparities up to max_disparity px) or calibrated pair."""
        left, right = _image(left, "left"), _image(right, "right")
        with self._lock:
            if calib is None:
                matches, report, _ = self._matcher.match_rectified(left, right, float(max_disparity))
            else:
                matches, report, _ = self._matcher.match_calibrated(left, right, _calibration(calib))
        return MatchResult(matches, _json.loads(report))


_matchers = {}
_matchers_lock = _threading.Lock()


def match(left, right, *, max_disparity=64, calib=None, preset="hnn-default", engine=None,
          **options):
    """Matches a stereo pair; numpy images, grey uint8 or BGR (uint16 too), same size.

    calib None: a rectified pair, disparities x_l - x_r up to max_disparity px. calib a path or a
    Calibration: gated by its F (rows when it is rectified; max_disparity then applies too).
    options: the ``hnnstereo match`` flags (max_features=1500, top_k=8, device="1"...).
    Returns a MatchResult (.matches float32 N x 6, .report dict). The Matcher of each setting is
    kept, so the OpenCL device is opened once.
    """
    if calib is not None:
        options = dict(options, max_disparity=max_disparity)
    key = (str(preset), str(engine), tuple(sorted(_overrides(options).items())))
    with _matchers_lock:
        matcher = _matchers.get(key)
        if matcher is None:
            matcher = Matcher(preset, engine, **options)
            if len(_matchers) >= 8:  # each holds an OpenCL context: keep the last few settings
                _matchers.pop(next(iter(_matchers)))
            _matchers[key] = matcher
    return matcher.match(left, right, max_disparity=max_disparity, calib=calib)


def pick(left, right, calib, **options):
    """`hnnstereo pick` on a calibrated pair -> the OBJECTS.json objects as a list of dicts
    ({id, centroid [x, y, z], height, yaw_deg, points, ...}, mm, tallest first)."""
    left, right = _image(left, "left"), _image(right, "right")
    text, _ = _sense_positions(left, right, _calibration(calib), _overrides(options))
    return _json.loads(text)["objects"]
