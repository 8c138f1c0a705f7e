"""hnnstereo.batch: many stereo pairs matched on a Dask distributed cluster.

    python -m hnnstereo.batch --pairs pairs.csv --out results            # a local cluster
    python -m hnnstereo.batch --pairs pairs.csv --out results --scheduler tcp://host:8786

    import hnnstereo.batch
    report = hnnstereo.batch.match_pairs("pairs.csv", "results", top_k=8)
    print(report.brief())

PAIRS.csv: a header naming the columns ``id``, ``left``, ``right`` and ``calib`` (a CAL.yml: a
calibrated pair) or ``max_disparity`` (px: a rectified pair), or both (a row fills one of them;
with a rectified calib, max_disparity bounds it too). Relative paths are relative to PAIRS.csv's
folder. Each pair's results: ``DIR/<id>/matches.csv`` (the bytes of ``hnnstereo match --out``)
and ``DIR/<id>/report.json`` (compact JSON: the keys of ``hnnstereo match --report`` plus the
pair's calib, max_disparity and batch_settings), each written atomically (a temporary file, then
a rename); ``DIR/manifest.csv``: id, status (done, failed, skipped), attempts, seconds, error per
pair.

Optional columns ``ground_truth`` (the left view's disparity map: PNG/PGM, 0 unknown, or PFM,
not finite unknown) and ``ground_truth_scale`` (stored value / scale = px, default 1): the pair's
report.json then holds "accuracy" and the summary the accuracy over such pairs.
``hnnstereo.batch.evaluate(dataset_dirs)``: accuracy over Middlebury sets, one task a set.

Needs ``pip install hnnstereo[batch]`` (dask distributed, OpenCV's cv2); the core module does not
import dask. Workers read the images from their paths, so every worker must see them at the same
path (a shared file system for a remote cluster). Each worker process keeps one Matcher per
setting for its life. A pair whose match fails, or whose worker dies while matching it, is
tried once more, then reported failed (attempts in the manifest count both); the others go on.
A re-run skips pairs whose report.json holds the same inputs and settings (resume).
"""

import asyncio as _asyncio
import csv as _csv
import json as _json
import math as _math
import os as _os
import sys as _sys
import time as _time
import uuid as _uuid

import hnnstereo as _hnnstereo

__all__ = ["BatchInputError", "BatchReport", "EvaluationReport", "Pair", "evaluate",
           "match_pairs", "read_pairs", "main"]

MANIFEST_COLUMNS = ["id", "status", "attempts", "seconds", "error"]
RESERVED_IDS = {"manifest.csv"}  # DIR/<id> must not be the manifest


class BatchInputError(ValueError):
    """Bad PAIRS.csv, output folder or settings, refused before any work (a one-line reason)."""


class Pair:
    """One pair to match: id (folder name under DIR), image paths, calib path or None,
    max_disparity (px) or None, and optionally the left view's ground-truth disparity map
    (ground_truth, a path; stored value / ground_truth_scale = px). Paths are absolute once
    checked."""

    __slots__ = ("id", "left", "right", "calib", "max_disparity", "ground_truth",
                 "ground_truth_scale")

    def __init__(self, id, left, right, calib=None, max_disparity=None, ground_truth=None,
                 ground_truth_scale=None):
        self.id, self.left, self.right = id, left, right
        self.calib, self.max_disparity = calib, max_disparity
        self.ground_truth, self.ground_truth_scale = ground_truth, ground_truth_scale

    def inputs(self):
        """The keys report.json records for this pair (resume compares them)."""
        inputs = {"left": self.left, "right": self.right, "calib": self.calib,
                  "max_disparity": self.max_disparity}
        if self.ground_truth is not None:
            inputs.update(ground_truth=self.ground_truth,
                          ground_truth_scale=self.ground_truth_scale)
        return inputs

    def __repr__(self):
        return f"<hnnstereo.batch.Pair {self.id!r} {self.left} {self.right}>"


# ---------------------------------------------------------------------------------------------
# Inputs: PAIRS.csv, the output folder and the settings, all checked before any work.

def _text(value):
    return "" if value is None else str(value).strip()


def _absolute(path, base):
    path = _os.path.expanduser(path)
    return _os.path.normpath(path if _os.path.isabs(path) else _os.path.join(base, path))


def _check_id(pair_id, where):
    if not pair_id:
        raise BatchInputError(f"{where}: empty id")
    separators = {"/", "\\", _os.sep} | ({_os.altsep} if _os.altsep else set())
    if any(s in pair_id for s in separators) or pair_id in {".", ".."} or "\0" in pair_id:
        raise BatchInputError(f"{where}: id {pair_id!r} is not a folder name (no path separators, "
                              "'.' or '..')")
    if any(ord(c) < 32 for c in pair_id) or pair_id in RESERVED_IDS:
        raise BatchInputError(f"{where}: id {pair_id!r} is not allowed (control characters or "
                              f"one of {sorted(RESERVED_IDS)})")


def _positive(text, where, name="max_disparity", unit=" px"):
    try:
        value = float(text)
    except ValueError:
        raise BatchInputError(f"{where}: {name} {text!r} is not a number") from None
    if not (value > 0 and _math.isfinite(value)):
        raise BatchInputError(f"{where}: {name} must be > 0{unit} (got {text!r})")
    return value


def _max_disparity(text, where):
    return _positive(text, where)


def _pair_from_row(row, where, base):
    """One PAIRS.csv row (a dict) -> a checked Pair with absolute paths."""
    pair_id = _text(row.get("id"))
    _check_id(pair_id, where)
    paths = {}
    for column in ("left", "right", "calib", "ground_truth"):
        text = _text(row.get(column))
        if not text:
            if column in ("calib", "ground_truth"):
                continue
            raise BatchInputError(f"{where} (id {pair_id!r}): empty {column}")
        path = _absolute(text, base)
        if not _os.path.isfile(path):
            raise BatchInputError(f"{where} (id {pair_id!r}): {column} {text!r} is not a file "
                                  f"({path})")
        paths[column] = path
    disparity_text = _text(row.get("max_disparity"))
    max_disparity = _max_disparity(disparity_text, where) if disparity_text else None
    if "calib" not in paths and max_disparity is None:
        raise BatchInputError(f"{where} (id {pair_id!r}): neither calib nor max_disparity (a "
                              "calibrated pair needs calib, a rectified pair max_disparity)")
    scale_text, scale = _text(row.get("ground_truth_scale")), None
    if "ground_truth" in paths:
        scale = _positive(scale_text, where, "ground_truth_scale", "") if scale_text else 1.0
        if "calib" in paths and not _calibration_rectified(paths["calib"], where):
            raise BatchInputError(f"{where} (id {pair_id!r}): a disparity ground_truth needs a "
                                  "rectified pair (its calib is not rectified)")
    elif scale_text:
        raise BatchInputError(f"{where} (id {pair_id!r}): ground_truth_scale without "
                              "ground_truth")
    return Pair(pair_id, paths["left"], paths["right"], paths.get("calib"), max_disparity,
                paths.get("ground_truth"), scale)


def _calibration_rectified(path, where):
    try:
        return _hnnstereo.load_calibration(path).rectified
    except (ValueError, RuntimeError) as error:
        raise BatchInputError(f"{where}: {' '.join(str(error).split())}") from None


def check_pairs(rows, base=".", source="pairs"):
    """Rows (dicts or Pairs) -> checked Pairs; relative paths against `base`. Raises
    BatchInputError on a missing column, an empty or duplicate id, an id that is not a folder
    name, a missing file or a bad max_disparity."""
    pairs, seen = [], {}
    for number, row in enumerate(rows, start=1):
        where = f"{source} row {number}"
        if isinstance(row, Pair):
            row = {"id": row.id, "left": row.left, "right": row.right, "calib": row.calib,
                   "max_disparity": row.max_disparity, "ground_truth": row.ground_truth,
                   "ground_truth_scale": row.ground_truth_scale}
        if not isinstance(row, dict):
            raise BatchInputError(f"{where}: a pair is a dict or a Pair, not {type(row).__name__}")
        if None in row:  # csv.DictReader puts a row's extra fields there
            raise BatchInputError(f"{where}: more fields than the header names")
        pair = _pair_from_row(row, where, base)
        if pair.id in seen:
            raise BatchInputError(f"{where}: duplicate id {pair.id!r} (first at row "
                                  f"{seen[pair.id]})")
        seen[pair.id] = number
        pairs.append(pair)
    if not pairs:
        raise BatchInputError(f"{source}: no pairs")
    return pairs


def read_pairs(path):
    """PAIRS.csv -> checked Pairs (paths relative to its folder). Raises BatchInputError."""
    path = _os.fspath(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:  # a spreadsheet's BOM too
            reader = _csv.DictReader(f)
            header = [name.strip() for name in (reader.fieldnames or [])]
            reader.fieldnames = header
            missing = [c for c in ("id", "left", "right") if c not in header]
            if missing or not ({"calib", "max_disparity"} & set(header)):
                raise BatchInputError(
                    f"{path}: the header must name id, left, right and calib or max_disparity "
                    f"(got {','.join(header) or 'nothing'})")
            if len(set(header)) != len(header):
                raise BatchInputError(f"{path}: the header names a column twice")
            rows = list(reader)
    except OSError as error:
        raise BatchInputError(f"cannot read {path}: {error.strerror or error}") from None
    except (UnicodeDecodeError, _csv.Error) as error:
        raise BatchInputError(f"{path} is not a UTF-8 CSV file: {error}") from None
    base = _os.path.dirname(_os.path.abspath(path))
    return check_pairs(rows, base, source=path)


def _output_paths(out_dir, pair):
    folder = _os.path.join(out_dir, pair.id)
    return _os.path.join(folder, "matches.csv"), _os.path.join(folder, "report.json")


def _check_outputs(pairs, out_dir, other_inputs=()):
    """Refuses an output folder that is a file, or outputs that would overwrite an input."""
    if _os.path.exists(out_dir) and not _os.path.isdir(out_dir):
        raise BatchInputError(f"--out {out_dir} exists and is not a folder")
    inputs = {_os.path.realpath(p) for p in other_inputs}
    for pair in pairs:
        inputs.update(_os.path.realpath(p) for p in (pair.left, pair.right, pair.calib,
                                                      pair.ground_truth) if p)
    outputs = [_os.path.join(out_dir, "manifest.csv")]
    for pair in pairs:
        folder = _os.path.join(out_dir, pair.id)
        outputs.append(folder)
        outputs.extend(_output_paths(out_dir, pair))
    for output in outputs:
        if _os.path.realpath(output) in inputs:
            raise BatchInputError(f"output {output} is an input: choose another --out")


def _settings(preset, engine, options):
    """The match settings as the Matcher takes them, checked by building one (one device open):
    an unknown option, preset or engine is refused here, before any work."""
    try:
        # As the CLI names and spells them ({"top-k": "8"}): top_k=8 and --top-k 8 are one
        # setting, and report.json records it as JSON keeps it (resume compares them).
        texts = _hnnstereo._overrides(options)
        if "max-disparity" in texts:
            raise BatchInputError("max_disparity is per pair: a PAIRS.csv column, not a batch "
                                  "option")
        settings = {"preset": str(preset), "engine": None if engine is None else str(engine),
                    "options": texts}
        _new_matcher(settings, texts)
    except (ValueError, RuntimeError) as error:
        raise BatchInputError(" ".join(str(error).split())) from None
    return settings


# ---------------------------------------------------------------------------------------------
# Ground truth and accuracy. The compiled module exports no evaluation (the pip build leaves out
# vision/eval, vision/CMakeLists.txt), so these follow `hnnstereo eval`'s definitions line by
# line: vision/eval/middlebury.cc (layouts, scales, unknown values, occlusion masks, search
# range), vision/eval/evaluation.cc (TruthAt, MatchError, ScoreMatches, density's Canny edges)
# and common/image.cc (the grey working copy); tests/python/test_batch.py checks the figures
# against `hnnstereo eval`'s EVAL.json.

def _grey(image):
    """common/image.cc GreyWorkingCopy: one channel (BGR(A) -> grey, grey+alpha -> grey), then
    8-bit (a 16-bit image stretched from its minimum to its maximum)."""
    import cv2
    import numpy as np

    if image.ndim == 3 and image.shape[2] == 2:
        image = image[:, :, 0]
    elif image.ndim == 3:
        code = cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        image = cv2.cvtColor(image, code)
    if image.dtype == np.uint8:
        return image
    values = image.astype(np.float64)
    low, high = float(values.min()), float(values.max())
    scale = 255.0 / (high - low) if high > low else 0.0
    return cv2.convertScaleAbs(values, alpha=scale, beta=-low * scale) if scale else \
        np.zeros(image.shape, np.uint8)


def read_pfm(path):
    """A grey PFM ("Pf"; negative scale: little-endian; rows stored bottom-to-top) -> float32,
    top row first (vision/eval/middlebury.cc ReadPfm)."""
    import numpy as np

    with open(path, "rb") as f:
        header = []
        while len(header) < 4:
            token = b""
            while True:
                byte = f.read(1)
                if not byte:
                    raise ValueError(f"malformed PFM header in {path}")
                if byte.isspace():
                    if token:
                        break
                    continue
                token += byte
            header.append(token)
        try:
            magic, width, height, scale = header[0], int(header[1]), int(header[2]), \
                float(header[3])
        except ValueError:
            raise ValueError(f"malformed PFM header in {path}") from None
        if magic != b"Pf" or width <= 0 or height <= 0 or scale == 0:
            raise ValueError(f"{path} is not a grey PFM (header {magic!r} {width} {height})")
        data = np.frombuffer(f.read(4 * width * height), dtype="<f4" if scale < 0 else ">f4")
    if data.size != width * height:
        raise ValueError(f"PFM {path} holds fewer values than its header's {width}x{height}")
    return np.flipud(data.reshape(height, width)).astype(np.float32)


def read_disparity(path, scale=1.0):
    """A left-view disparity map -> float32 px, NaN where unknown. PFM: the values as stored
    (not finite = unknown); PNG/PGM: stored value / scale, 0 = unknown (middlebury.cc
    ReadScaledDisparity)."""
    import cv2
    import numpy as np

    if path.lower().endswith(".pfm"):
        disparity = read_pfm(path)
        disparity = np.where(np.isfinite(disparity), disparity, np.nan).astype(np.float32)
        return disparity / np.float32(scale) if scale != 1.0 else disparity
    stored = cv2.imread(path, cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH)
    if stored is None:
        raise ValueError(f"cannot read the ground truth {path}")
    values = stored.astype(np.float32)
    # float / double, then float: as `static_cast<float>(in[x] / scale)`.
    scaled = (values.astype(np.float64) / scale).astype(np.float32)
    return np.where(values > 0, scaled, np.float32(np.nan)).astype(np.float32)


def _left_right_mask(left, right, tolerance_px=1.0):
    """middlebury.cc LeftRightConsistentMask: the left disparity d at (x, y) is known, x - d
    lands in the right image, and the right disparity there agrees within tolerance_px."""
    import numpy as np

    height, width = left.shape
    xs = np.arange(width, dtype=np.float64)[None, :].repeat(height, axis=0)
    with np.errstate(invalid="ignore"):
        target = xs - left.astype(np.float64)
        xr = np.where(target >= 0, np.floor(target + 0.5), np.ceil(target - 0.5))  # lround
    inside = np.isfinite(left) & (xr >= 0) & (xr < width)
    rows = np.arange(height)[:, None].repeat(width, axis=1)
    dr = np.full(left.shape, np.nan, np.float32)
    dr[inside] = right[rows[inside], xr[inside].astype(np.int64)]
    with np.errstate(invalid="ignore"):
        return inside & np.isfinite(dr) & (np.abs(dr - left) <= tolerance_px)


_MIDDLEBURY_LAYOUTS = [  # middlebury.cc FindLayoutFiles, in its order: name, role -> files
    ("middlebury2014", {"left": ["im0.png"], "right": ["im1.png"],
                        "disparity": ["disp0GT.pfm", "disp0.pfm"],
                        "right_disparity": ["disp1GT.pfm"], "mask": ["mask0nocc.png"]}),
    ("middlebury2001-tsukuba", {"left": ["scene1.row3.col3.ppm", "scene1.row3.col3.png"],
                                "right": ["scene1.row3.col4.ppm", "scene1.row3.col4.png"],
                                "disparity": ["truedisp.row3.col3.pgm", "truedisp.row3.col3.png"],
                                "mask": ["nonocc.png"]}),
    ("middlebury2005", {"left": ["view1.png"], "right": ["view5.png"], "disparity": ["disp1.png"],
                        "right_disparity": ["disp5.png"], "mask": ["nonocc.png"]}),
    ("middlebury2001", {"left": ["im2.png", "im2.ppm", "im2.pgm"],
                        "right": ["im6.png", "im6.ppm", "im6.pgm"], "disparity": ["disp2.pgm"],
                        "right_disparity": ["disp6.pgm"], "mask": ["nonocc.png"]}),
    ("middlebury2003", {"left": ["im2.png", "im2.ppm", "im2.pgm"],
                        "right": ["im6.png", "im6.ppm", "im6.pgm"], "disparity": ["disp2.png"],
                        "right_disparity": ["disp6.png"], "mask": ["nonocc.png"]}),
]


def middlebury_layout(directory):
    """(layout name, {role: path}) of a Middlebury folder, or None when it is not one."""
    if not _os.path.isdir(directory):
        return None
    for name, roles in _MIDDLEBURY_LAYOUTS:
        found = {}
        for role, names in roles.items():
            path = next((_os.path.join(directory, n) for n in names
                         if _os.path.isfile(_os.path.join(directory, n))), None)
            if path is not None:
                found[role] = path
        if all(role in found for role in ("left", "right", "disparity")):
            return name, found
    return None


def _middlebury_scale(layout, width):
    """Stored value / scale = px (middlebury.cc: Scale2003, Scale2005)."""
    if layout == "middlebury2005":
        return 3.0 if width < 500 else 2.0 if width < 900 else 1.0
    if layout == "middlebury2003":
        return 4.0 if width < 600 else 2.0
    return {"middlebury2001-tsukuba": 16.0, "middlebury2001": 8.0}.get(layout, 1.0)


def load_middlebury(directory):
    """A Middlebury folder -> dict: layout, left, right (paths), disparity (float32 px, NaN
    unknown), nonoccluded (bool), occlusion_source, max_disparity (the ground truth's maximum
    + 1, rounded up to 16, as `hnnstereo eval` searches). Raises ValueError."""
    import cv2
    import numpy as np

    found = middlebury_layout(directory)
    if found is None:
        raise ValueError(f"{directory} is not a recognised Middlebury set")
    layout, files = found
    left = cv2.imread(files["left"], cv2.IMREAD_UNCHANGED)
    if left is None:
        raise ValueError(f"cannot read the left image {files['left']}")
    scale = _middlebury_scale(layout, left.shape[1])
    disparity = read_disparity(files["disparity"], scale)
    if disparity.shape != left.shape[:2]:
        raise ValueError(f"ground truth {files['disparity']} is {disparity.shape[1]}x"
                         f"{disparity.shape[0]}, the images {left.shape[1]}x{left.shape[0]}")
    known = np.isfinite(disparity)
    if "mask" in files:
        mask = cv2.imread(files["mask"], cv2.IMREAD_GRAYSCALE)
        if mask is None or mask.shape != disparity.shape:
            raise ValueError(f"cannot use occlusion mask {files['mask']}")
        nonoccluded = (mask > (254 if layout == "middlebury2014" else 0)) & known
        source = "mask"
    else:
        right = (read_disparity(files["right_disparity"], scale)
                 if "right_disparity" in files else None)
        if right is not None and right.shape == disparity.shape:
            nonoccluded, source = _left_right_mask(disparity, right), "left-right check"
        else:
            nonoccluded, source = known.copy(), "none"
    max_truth = float(disparity[known].max()) if known.any() else 0.0
    return {"layout": layout, "left": files["left"], "right": files["right"],
            "disparity": disparity, "nonoccluded": nonoccluded, "occlusion_source": source,
            "max_disparity": 16.0 * _math.ceil((max_truth + 1.0) / 16.0)}


ACCURACY_COUNTS = ["n_matches", "n_with_truth", "n_nonoccluded", "n_occluded", "correct_1px",
                   "correct_2px", "n_edges_with_truth"]


def _edges_with_truth(grey, known, options):
    """Density's denominator (evaluation.cc EvaluatePair): the left image's Canny edge pixels
    (the setting's canny-low / canny-high, aperture 3, L1 gradient; none within 4 px of a border,
    features.cc DetectCanny, no cap) with ground truth. None for another feature detector."""
    import cv2

    if options.get("features", "canny") != "canny":
        return None
    edges = cv2.Canny(grey, float(options.get("canny-low", 50.0)),
                      float(options.get("canny-high", 150.0)), apertureSize=3, L2gradient=False)
    border = 4
    inner = (edges != 0)[border:-border, border:-border] & known[border:-border, border:-border]
    return int(inner.sum())


def score_matches(matches, disparity, nonoccluded, n_edges_with_truth):
    """evaluation.cc ScoreMatches for a rectified pair: a match counts where its left pixel
    (rounded) has ground truth d; its error is the distance from its right point to (xl - d, yl);
    correct within 1 (2) px, over the non-occluded ones -> counts (ACCURACY_COUNTS)."""
    import numpy as np

    counts = dict.fromkeys(ACCURACY_COUNTS, 0)
    counts["n_matches"] = int(len(matches))
    counts["n_edges_with_truth"] = n_edges_with_truth
    if len(matches) == 0:
        return counts
    xl, yl = matches[:, 0].astype(np.float64), matches[:, 1].astype(np.float64)
    xr, yr = matches[:, 2].astype(np.float64), matches[:, 3].astype(np.float64)
    x = np.where(xl >= 0, np.floor(xl + 0.5), np.ceil(xl - 0.5))  # std::lround
    y = np.where(yl >= 0, np.floor(yl + 0.5), np.ceil(yl - 0.5))
    height, width = disparity.shape
    inside = (x >= 0) & (y >= 0) & (x < width) & (y < height)
    d = np.full(len(matches), np.nan)
    xi, yi = x[inside].astype(np.int64), y[inside].astype(np.int64)
    d[inside] = disparity[yi, xi]
    visible = np.zeros(len(matches), bool)
    visible[inside] = nonoccluded[yi, xi]
    known = np.isfinite(d)
    error = np.hypot(xr - (xl - d), yr - yl)
    counts.update(n_with_truth=int(known.sum()), n_nonoccluded=int((known & visible).sum()),
                  n_occluded=int((known & ~visible).sum()),
                  correct_1px=int((known & visible & (error <= 1.0)).sum()),
                  correct_2px=int((known & visible & (error <= 2.0)).sum()))
    return counts


def accuracy_figures(counts):
    """Counts (one pair's, or summed) -> precision_1px, precision_2px (shares of the non-occluded
    matches with ground truth) and density (matches with ground truth / edges with ground truth;
    None when not known), as EVAL.json names them."""
    nonoccluded, edges = counts["n_nonoccluded"], counts.get("n_edges_with_truth")
    return {"precision_1px": counts["correct_1px"] / nonoccluded if nonoccluded else 0.0,
            "precision_2px": counts["correct_2px"] / nonoccluded if nonoccluded else 0.0,
            "density": counts["n_with_truth"] / edges if edges else None}


def sum_counts(rows):
    """Counts summed over pairs (n_edges_with_truth None when a pair's is not known)."""
    total = dict.fromkeys(ACCURACY_COUNTS, 0)
    for counts in rows:
        for key in ACCURACY_COUNTS:
            if total[key] is not None:
                total[key] = None if counts.get(key) is None else total[key] + counts[key]
    return total


def _accuracy(matches, left_image, disparity, nonoccluded, options):
    import numpy as np

    if disparity.shape != left_image.shape[:2]:
        raise ValueError(f"the ground truth is {disparity.shape[1]}x{disparity.shape[0]}, the "
                         f"left image {left_image.shape[1]}x{left_image.shape[0]}")
    edges = _edges_with_truth(_grey(left_image), np.isfinite(disparity), options)
    counts = score_matches(matches, disparity, nonoccluded, edges)
    counts.update(accuracy_figures(counts))
    return counts


# ---------------------------------------------------------------------------------------------
# On the workers: one Matcher per setting for the worker process's life; one task per pair.

_worker_matchers = {}  # settings key -> Matcher, kept for the worker process's life


def _new_matcher(settings, options):
    """engine None: hnnstereo.Matcher's own default, as hnnstereo.match has it."""
    engine = {} if settings["engine"] is None else {"engine": settings["engine"]}
    return _hnnstereo.Matcher(settings["preset"], **engine, **options)


def _matcher(settings, options):
    key = (settings["preset"], settings["engine"], tuple(sorted(options.items())))
    matcher = _worker_matchers.get(key)
    if matcher is None:
        matcher = _new_matcher(settings, options)
        _worker_matchers[key] = matcher
    return matcher


def matches_csv(matches):
    """MATCHES.csv text as `hnnstereo match` writes it (vision/stereo/match_io.cc): the float32
    values printed through double, 3 decimals for pixels and 6 for activation and confidence."""
    lines = ["xl,yl,xr,yr,activation,confidence\n"]
    lines.extend("%.3f,%.3f,%.3f,%.3f,%.6f,%.6f\n" % tuple(row) for row in matches.tolist())
    return "".join(lines)


def _write_atomically(path, text):
    """A temporary file in the same folder, then a rename: a reader sees the whole file or none;
    a worker killed while writing leaves at most a hidden .tmp-* file."""
    folder, name = _os.path.split(path)
    temporary = _os.path.join(folder, f".{name}.tmp-{_os.getpid()}-{_uuid.uuid4().hex[:8]}")
    try:
        with open(temporary, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
        _os.replace(temporary, path)
    except BaseException:
        if _os.path.exists(temporary):
            _os.remove(temporary)
        raise


def _match_pair_files(pair, settings):
    """Reads and matches one pair on this worker -> (matches float32 N x 6, report dict); the
    report holds "accuracy" (counts and figures) when the pair has a ground_truth."""
    import cv2  # on the workers only (the images are read where they are matched)

    images = []
    for side, path in (("left", pair.left), ("right", pair.right)):
        image = cv2.imread(path, cv2.IMREAD_UNCHANGED)
        if image is None:
            raise ValueError(f"cannot read the {side} image {path}")
        images.append(image)
    options = dict(settings["options"])
    if pair.calib is not None:  # as hnnstereo.match: max_disparity is a Matcher option then
        options["max-disparity"] = str(pair.max_disparity if pair.max_disparity is not None
                                      else 64.0)
        result = _matcher(settings, options).match(*images, calib=pair.calib)
    else:
        result = _matcher(settings, options).match(*images, max_disparity=pair.max_disparity)
    if pair.ground_truth is not None:
        import numpy as np

        disparity = read_disparity(pair.ground_truth, pair.ground_truth_scale)
        # No occlusion mask: every pixel with ground truth counts as visible (as `hnnstereo
        # eval` does for a set without a mask or a right-view map).
        result.report["accuracy"] = _accuracy(result.matches, images[0], disparity,
                                              np.isfinite(disparity), settings["options"])
    return result.matches, result.report


RUNNING_MARKER = ".running-"  # DIR/<id>/.running-<task key>-<worker pid>: a run began


def _markers(out_dir, pair_id, key):
    prefix = f"{RUNNING_MARKER}{key}-"
    try:
        names = _os.listdir(_os.path.join(out_dir, pair_id))
    except OSError:
        return []
    return [_os.path.join(out_dir, pair_id, n) for n in names if n.startswith(prefix)]


def run_pair(pair, run_key, out_dir, settings):
    """The task of one pair on a worker: match, write matches.csv then report.json (each
    atomically; report.json last, so its presence means the pair is complete) -> a dict with
    id, status ("done"/"failed"), seconds, error, n_matches, pid, matchers (this process's
    Matcher count) and accuracy (None without ground truth). Never raises for a pair's own
    failure. While it runs, an empty DIR/<id>/.running-<run_key>-<pid> marker exists: one left
    behind is a run whose worker died (the driver counts it as an attempt, then removes it)."""
    start = _time.perf_counter()
    folder = _os.path.join(out_dir, pair.id)
    _os.makedirs(folder, exist_ok=True)
    marker = _os.path.join(folder, f"{RUNNING_MARKER}{run_key}-{_os.getpid()}")
    open(marker, "w").close()
    try:
        matches, report = _match_pair_files(pair, settings)
        report.update(pair.inputs())
        report["batch_settings"] = settings
        matches_path, report_path = _output_paths(out_dir, pair)
        _os.makedirs(_os.path.dirname(matches_path), exist_ok=True)
        _write_atomically(matches_path, matches_csv(matches))
        # Compact: Python's C encoder serves only indent=None (an indented Teddy-size report,
        # with its per-match table, costs about half a match).
        _write_atomically(report_path, _json.dumps(report, separators=(",", ":")) + "\n")
        status, error, n_matches = "done", "", len(matches)
        accuracy = report.get("accuracy")
    except Exception as exception:  # reported in the manifest, retried once by the driver
        status, n_matches, accuracy = "failed", 0, None
        error = " ".join(f"{type(exception).__name__}: {exception}".split())
    _os.remove(marker)
    return {"id": pair.id, "status": status, "error": error, "n_matches": n_matches,
            "seconds": _time.perf_counter() - start, "pid": _os.getpid(),
            "matchers": len(_worker_matchers), "accuracy": accuracy}


# ---------------------------------------------------------------------------------------------
# On the client: resume, submit, retry once, progress and the manifest.

def _already_done(pair, out_dir, settings):
    """DIR/<id>/report.json (written last) when it records this pair's inputs and settings (its
    accuracy then counts in the summary), else None."""
    matches_path, report_path = _output_paths(out_dir, pair)
    try:
        with open(report_path, encoding="utf-8") as f:
            report = _json.load(f)
    except (OSError, ValueError):
        return None
    if not isinstance(report, dict):
        return None
    recorded = {key: report.get(key) for key in pair.inputs()}
    if ("ground_truth" not in pair.inputs()) != ("ground_truth" not in report):
        return None
    done = (recorded == pair.inputs() and report.get("batch_settings") == settings
            and _os.path.isfile(matches_path))
    return report if done else None


def _remove_stale(pair, out_dir):
    """Removes an earlier run's outputs of a pair about to be matched again (report.json first),
    so the folder never holds results the manifest does not describe."""
    for path in reversed(_output_paths(out_dir, pair)):
        if _os.path.exists(path):
            _os.remove(path)
    for path in _markers(out_dir, pair.id, ""):  # an earlier run's dead workers
        _os.remove(path)


def _write_manifest(out_dir, rows):
    lines = [",".join(MANIFEST_COLUMNS) + "\n"]
    for row in rows:
        fields = [row["id"], row["status"], str(row["attempts"]),
                  "" if row["seconds"] is None else f"{row['seconds']:.3f}", row["error"]]
        lines.append(",".join(_csv_field(f) for f in fields) + "\n")
    _write_atomically(_os.path.join(out_dir, "manifest.csv"), "".join(lines))


def _csv_field(text):
    if any(c in text for c in ',"\n\r'):
        return '"' + text.replace('"', '""') + '"'
    return text


class Progress:
    """Pairs done / total, pairs a second and ETA on a stream: one \\r line on a terminal, a line
    every `interval_s` seconds otherwise; silent when stream is None."""

    def __init__(self, total, stream=_sys.stderr, interval_s=10.0):
        self.total, self.stream, self.finished, self.failed = total, stream, 0, 0
        self.terminal = bool(stream is not None and hasattr(stream, "isatty") and stream.isatty())
        self.interval_s = 0.2 if self.terminal else interval_s
        self.start = _time.perf_counter()
        self.last = self.start

    def line(self):
        elapsed = _time.perf_counter() - self.start
        rate = self.finished / elapsed if elapsed > 0 else 0.0
        left = self.total - self.finished
        eta = f"{left / rate:.0f} s" if rate > 0 else "-"
        failed = f", {self.failed} failed" if self.failed else ""
        return f"{self.finished}/{self.total} pairs{failed}, {rate:.2f} pairs/s, ETA {eta}"

    def update(self, finished, failed, final=False):
        self.finished, self.failed = finished, failed
        now = _time.perf_counter()
        if self.stream is None or (not final and (now - self.last < self.interval_s
                                                  or finished == self.total)):
            return  # the last pair's line is the final one
        self.last = now
        end = "\n" if final or not self.terminal else ""
        self.stream.write(("\r" if self.terminal else "") + self.line() + end)
        self.stream.flush()


class BatchReport:
    """What a batch did: rows (one per pair: id, status, attempts, seconds, error, accuracy, plus
    pid and matchers for the pairs matched in this run), counts, wall seconds and workers;
    accuracy: the counts and figures summed over the pairs with a ground_truth (None: none)."""

    def __init__(self, rows, seconds, workers, out_dir):
        self.rows, self.seconds, self.workers, self.out_dir = rows, seconds, workers, out_dir
        self.done = sum(r["status"] == "done" for r in rows)
        self.failed = sum(r["status"] == "failed" for r in rows)
        self.skipped = sum(r["status"] == "skipped" for r in rows)
        scored = [r["accuracy"] for r in rows if r.get("accuracy")]
        self.accuracy = None
        if scored:
            self.accuracy = sum_counts(scored)
            self.accuracy.update(accuracy_figures(self.accuracy), n_pairs=len(scored))

    @property
    def pairs_per_second(self):
        return self.done / self.seconds if self.seconds > 0 else 0.0

    def brief(self):
        text = (f"{self.done} matched, {self.skipped} skipped (done before), {self.failed} failed "
                f"of {len(self.rows)} pairs in {self.seconds:.1f} s on {self.workers} workers: "
                f"{self.pairs_per_second:.2f} pairs/s; manifest "
                f"{_os.path.join(self.out_dir, 'manifest.csv')}")
        if self.accuracy is not None:
            text += "\n" + _accuracy_line(self.accuracy, f"{self.accuracy['n_pairs']} pairs with "
                                           "ground truth")
        for row in [r for r in self.rows if r["status"] == "failed"][:5]:
            text += f"\nfailed {row['id']}: {row['error']}"
        if self.failed > 5:
            text += f"\n... and {self.failed - 5} more failed pairs (manifest.csv)"
        return text


def _accuracy_line(figures, what):
    density = ("density n/a (not Canny features)" if figures["density"] is None
               else f"density {figures['density']:.3f}")
    return (f"accuracy on {what}: {100 * figures['precision_1px']:.1f} % within 1 px "
            f"({figures['correct_1px']} of {figures['n_nonoccluded']} non-occluded matches with "
            f"ground truth), {100 * figures['precision_2px']:.1f} % within 2 px, {density}")


def _submit(client, task, items, attempt, **arguments):
    token = _uuid.uuid4().hex[:8]
    keys = [f"hnnstereo-{task.__name__}-{token}-{attempt}-{index}"
            for index in range(len(items))]
    futures = client.map(task, items, keys, key=keys, pure=False, **arguments)
    return dict(zip(futures, items))


def _failed_result(item, exception):
    error = " ".join(f"{type(exception).__name__}: {exception}".split())
    return {"id": item.id, "status": "failed", "error": error, "n_matches": 0, "seconds": None,
            "pid": None, "matchers": None, "accuracy": None}


def _scheduler_deaths(keys, dask_scheduler=None):
    """On the scheduler: key -> the times a worker died while running that task (TaskState
    .suspicious; the scheduler reruns such a task elsewhere up to allowed-failures times)."""
    tasks = dask_scheduler.tasks
    return {key: tasks[key].suspicious for key in keys if key in tasks}


def _allowed_failures(client):
    try:
        return int(client.run_on_scheduler(
            lambda dask_scheduler=None: dask_scheduler.allowed_failures))
    except Exception:  # a scheduler that refuses run_on_scheduler: dask's default
        import dask

        return int(dask.config.get("distributed.scheduler.allowed-failures"))


def _drive(client, task, items, arguments, rows, progress, runs_died=None, on_change=None,
           interval_s=5.0):
    """Runs task(item, key, **arguments) for every item (one task each), fills `rows` (id -> row)
    as results come, and calls on_change(rows) every interval_s seconds.

    A row's attempts count the runs of its task that began on a worker, a run whose worker died
    included; an item that failed (or died) on its first attempt is submitted once more, then
    reported failed. runs_died(item, key) -> the runs of that task whose worker died (run_pair's
    markers); the scheduler reruns such a task by itself up to its allowed-failures (the local
    cluster here sets 0, so a death reaches this loop at once). Without runs_died, the
    scheduler's count (TaskState.suspicious) stands in: it also counts a task that was only
    waiting on the dead worker."""
    from distributed import KilledWorker, as_completed

    allowed = _allowed_failures(client) if runs_died is None else None
    by_future = _submit(client, task, items, 1, **arguments)
    submissions = dict.fromkeys((item.id for item in items), 1)
    completed = as_completed(list(by_future))
    finished, failed, last_change, unchecked = 0, 0, _time.perf_counter(), {}

    def count_reruns():  # the scheduler's reruns of finished tasks (no runs_died)
        if unchecked:
            try:
                deaths = client.run_on_scheduler(_scheduler_deaths,
                                                 [f.key for f in unchecked])
            except Exception:  # the counts are for the manifest only
                deaths = {}
            for finished_future, item_id in unchecked.items():
                rows[item_id]["attempts"] += deaths.get(finished_future.key, 0)
            unchecked.clear()

    for future in completed:
        item = by_future.pop(future)
        row = rows[item.id]
        died = runs_died(item, future.key) if runs_died is not None else 0
        try:
            result = future.result()
            row["attempts"] += 1 + died
            if runs_died is None:
                unchecked[future] = item.id
        except KilledWorker as exception:  # its workers died while it was sent to them
            result = _failed_result(item, exception)
            row["attempts"] += died if runs_died is not None else allowed + 1
        except Exception as exception:  # a lost worker's data, a pickling error...
            result = _failed_result(item, exception)
            row["attempts"] += max(died, 1)
        row.update(status=result["status"], error=result["error"], seconds=result["seconds"],
                   pid=result["pid"], matchers=result["matchers"], accuracy=result["accuracy"])
        # A task lost with a worker before it began is sent again without counting an attempt;
        # four sends at most (a cluster whose workers keep dying).
        if (result["status"] == "failed" and row["attempts"] < 2
                and submissions[item.id] < 4):
            submissions[item.id] += 1
            retry = _submit(client, task, [item], submissions[item.id], **arguments)
            by_future.update(retry)
            completed.update(list(retry))
        else:
            finished += 1
            failed += result["status"] == "failed"
            progress.update(finished, failed)
        if _time.perf_counter() - last_change > interval_s:
            count_reruns()
            if on_change is not None:
                on_change(rows)
            last_change = _time.perf_counter()
        del future
    count_reruns()
    progress.update(finished, failed, final=True)


def _pair_runs_died(out_dir):
    def runs_died(pair, key):
        leftover = _markers(out_dir, pair.id, key)
        for path in leftover:
            _os.remove(path)
        return len(leftover)
    return runs_died


def _require_distributed():
    try:
        import distributed  # noqa: F401
    except ImportError as error:
        raise ImportError(f"hnnstereo.batch needs dask distributed (pip install "
                          f"'hnnstereo[batch]'): {error}") from None


def _workers_of(client):
    try:
        return len(client.scheduler_info().get("workers", {}))
    except Exception:  # the count is for the report only
        return 0


def match_pairs(pairs, out_dir, client=None, *, workers=None, preset="hnn-default",
                engine=None, progress=None, **match_options):
    """Matches every pair on a Dask cluster; results under out_dir (module docstring).

    pairs: a PAIRS.csv path, or an iterable of dicts/Pairs (id, left, right, calib and/or
    max_disparity, optionally ground_truth and ground_truth_scale; relative paths against the
    current folder). client: a distributed.Client; None starts a LocalCluster of `workers`
    processes (default: the CPU count), one thread each, and closes it at the end. preset,
    engine, match_options: as hnnstereo.match (the ``hnnstereo match`` flags; max_disparity is
    per pair). progress: a stream for the progress line (None: silent). Returns a BatchReport
    (.accuracy: over the pairs with ground truth). Raises BatchInputError before any work on bad
    pairs, outputs or settings.
    """
    _require_distributed()
    out_dir = _os.path.abspath(_os.fspath(out_dir))
    if isinstance(pairs, (str, bytes, _os.PathLike)):
        pairs_csv = _os.path.abspath(_os.fspath(pairs))
        pairs, other_inputs = read_pairs(pairs_csv), [pairs_csv]
    else:
        pairs, other_inputs = check_pairs(list(pairs), _os.getcwd()), []
    _check_outputs(pairs, out_dir, other_inputs)
    settings = _settings(preset, engine, match_options)
    if client is not None and workers is not None:
        raise BatchInputError("workers is for the local cluster: a given client has its own")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise BatchInputError(f"workers must be an integer >= 1 (got {workers!r})")
    try:
        rows, todo = _plan(pairs, out_dir, settings)
    except OSError as error:
        raise BatchInputError(f"cannot write to --out {out_dir}: "
                              f"{error.strerror or error}") from None
    return _run(todo, out_dir, client, workers, settings, rows, progress)


def _plan(pairs, out_dir, settings):
    """Creates out_dir, marks the pairs done by an earlier run `skipped`, removes the others'
    stale outputs and writes the first manifest -> (rows by id, the pairs to match)."""
    _os.makedirs(out_dir, exist_ok=True)
    rows, todo = {}, []
    for pair in pairs:
        done_before = _already_done(pair, out_dir, settings)
        rows[pair.id] = {"id": pair.id, "status": "skipped" if done_before else "pending",
                         "attempts": 0, "seconds": None, "error": "", "pid": None,
                         "matchers": None,
                         "accuracy": done_before.get("accuracy") if done_before else None}
        if not done_before:
            _remove_stale(pair, out_dir)
            todo.append(pair)
    _write_manifest(out_dir, rows.values())
    return rows, todo


class _Cluster:
    """`client`, or a LocalCluster of `workers` processes (one thread each) and its client,
    closed on exit. The local scheduler reruns no task whose worker died (allowed-failures 0:
    _drive counts and retries it) and sends a worker one task at a time (worker-saturation 1.0:
    a dead worker held only the task it was running)."""

    def __init__(self, client, workers):
        self.client, self.workers, self.cluster, self.own = client, workers, None, False

    def __enter__(self):
        if self.client is None:
            import dask
            from distributed import Client, LocalCluster

            with dask.config.set({"distributed.scheduler.allowed-failures": 0,
                                  "distributed.scheduler.worker-saturation": 1.0}):
                # No dashboard; the scheduler's own HTTP routes on a free port (the default
                # 8787 may be another cluster's).
                self.cluster = LocalCluster(
                    n_workers=self.workers or _os.cpu_count() or 1, threads_per_worker=1,
                    processes=True, dashboard_address=None,
                    scheduler_kwargs={"dashboard_address": ":0"}, silence_logs=40)
            self.client, self.own = Client(self.cluster), True
        return self.client

    def __exit__(self, *exception):
        if self.own:
            self.client.close()
            self.cluster.close()


def _run(todo, out_dir, client, workers, settings, rows, progress_stream):
    start = _time.perf_counter()
    n_workers = 0
    try:
        if todo:
            with _Cluster(client, workers) as active:
                _drive(active, run_pair, todo, {"out_dir": out_dir, "settings": settings}, rows,
                       Progress(len(todo), progress_stream), _pair_runs_died(out_dir),
                       on_change=lambda rows: _write_manifest(out_dir, rows.values()))
                n_workers = _workers_of(active)
        elif client is not None:
            n_workers = _workers_of(client)
    finally:
        _write_manifest(out_dir, rows.values())
    return BatchReport(list(rows.values()), _time.perf_counter() - start, n_workers, out_dir)


# ---------------------------------------------------------------------------------------------
# Evaluation: accuracy over Middlebury data sets, one task a set.

class Dataset:
    """One Middlebury folder to evaluate: id (its path as given), directory (absolute)."""

    __slots__ = ("id", "directory")

    def __init__(self, id, directory):
        self.id, self.directory = id, directory

    def __repr__(self):
        return f"<hnnstereo.batch.Dataset {self.directory}>"


def find_datasets(dataset_dirs):
    """Folders -> Datasets: a folder that is a Middlebury set, else its immediate subfolders that
    are (sorted), as `hnnstereo eval --dataset` takes them. Raises BatchInputError when a folder
    holds none or a set is named twice."""
    if isinstance(dataset_dirs, (str, bytes, _os.PathLike)):
        dataset_dirs = [dataset_dirs]
    datasets, seen = [], set()
    for given in dataset_dirs:
        directory = _os.path.abspath(_os.fspath(given))
        if middlebury_layout(directory) is not None:
            found = [directory]
        else:
            try:
                names = sorted(_os.listdir(directory))
            except OSError as error:
                raise BatchInputError(f"cannot read the dataset folder {given}: "
                                      f"{error.strerror or error}") from None
            found = [_os.path.join(directory, n) for n in names
                     if middlebury_layout(_os.path.join(directory, n)) is not None]
            if not found:
                raise BatchInputError(f"{given} is not a Middlebury set and holds none (layouts: "
                                      "im0/im1 + disp0GT.pfm, im2/im6 + disp2.png/pgm, view1/"
                                      "view5 + disp1.png, Tsukuba's scene1.row3.col3/4)")
        for directory in found:
            if directory in seen:
                raise BatchInputError(f"the dataset {directory} is named twice")
            seen.add(directory)
            datasets.append(Dataset(directory, directory))
    if not datasets:
        raise BatchInputError("no datasets")
    return datasets


def evaluate_dataset(dataset, run_key, settings):
    """The task of one data set on a worker: its rectified pair matched over [0, the ground
    truth's maximum rounded up to 16] px (as `hnnstereo eval`), then scored -> a dict with id,
    status, error, seconds, n_matches, pid, matchers and accuracy (counts, figures, layout,
    occlusion_source, max_disparity). Never raises for the set's own failure."""
    import cv2

    start = _time.perf_counter()
    try:
        truth = load_middlebury(dataset.directory)
        images = [cv2.imread(truth[side], cv2.IMREAD_UNCHANGED) for side in ("left", "right")]
        options = dict(settings["options"])
        result = _matcher(settings, options).match(*images,
                                                   max_disparity=truth["max_disparity"])
        accuracy = _accuracy(result.matches, images[0], truth["disparity"], truth["nonoccluded"],
                             options)
        accuracy.update(layout=truth["layout"], occlusion_source=truth["occlusion_source"],
                        max_disparity=truth["max_disparity"])
        status, error, n_matches = "done", "", len(result.matches)
    except Exception as exception:
        status, error, n_matches, accuracy = "failed", " ".join(
            f"{type(exception).__name__}: {exception}".split()), 0, None
    return {"id": dataset.id, "status": status, "error": error, "n_matches": n_matches,
            "seconds": _time.perf_counter() - start, "pid": _os.getpid(),
            "matchers": len(_worker_matchers), "accuracy": accuracy}


class EvaluationReport:
    """Accuracy per data set and overall: rows (id = the set's folder, status, attempts,
    seconds, error, accuracy: n_matches, n_with_truth, n_nonoccluded, n_occluded, correct_1px,
    correct_2px, n_edges_with_truth, precision_1px, precision_2px, density, layout,
    occlusion_source, max_disparity), overall (the counts summed over the sets done, and their
    figures: edge-weighted as `hnnstereo eval`'s overall rows), seconds, workers."""

    def __init__(self, rows, seconds, workers):
        self.rows, self.seconds, self.workers = rows, seconds, workers
        self.failed = sum(r["status"] == "failed" for r in rows)
        scored = [r["accuracy"] for r in rows if r["status"] == "done" and r["accuracy"]]
        self.overall = sum_counts(scored)
        self.overall.update(accuracy_figures(self.overall), n_datasets=len(scored))

    def brief(self):
        lines = [_accuracy_line(r["accuracy"], _os.path.basename(r["id"]) or r["id"])
                 for r in self.rows if r["status"] == "done"]
        lines += [f"failed {r['id']}: {r['error']}" for r in self.rows if r["status"] == "failed"]
        lines.append(_accuracy_line(self.overall, f"{self.overall['n_datasets']} data sets "
                                    "(overall)") + f"; {self.seconds:.1f} s on {self.workers} "
                     "workers")
        return "\n".join(lines)


def evaluate(dataset_dirs, client=None, *, workers=None, preset="hnn-default", engine=None,
             progress=None, **match_options):
    """Accuracy of a setting over Middlebury data sets with ground truth, one task a set on a
    Dask cluster (`hnnstereo eval`'s figures for its first preset, without the baselines).

    dataset_dirs: a folder or folders, each a set or a folder of sets (/work/shared/datasets
    layouts: 2001, Tsukuba, 2003, 2005/2006, 2014 and ETH3D's im0/im1 + disp0.pfm). client,
    workers, preset, engine, match_options, progress: as match_pairs (max_disparity comes from
    each set's ground truth). Nothing is written. Returns an EvaluationReport (.rows per set,
    .overall, .brief()); a set that fails (twice) is reported in its row, the others go on.
    Raises BatchInputError before any work on bad folders or settings.
    """
    _require_distributed()
    datasets = find_datasets(dataset_dirs)
    settings = _settings(preset, engine, match_options)
    if client is not None and workers is not None:
        raise BatchInputError("workers is for the local cluster: a given client has its own")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise BatchInputError(f"workers must be an integer >= 1 (got {workers!r})")
    rows = {d.id: {"id": d.id, "status": "pending", "attempts": 0, "seconds": None, "error": "",
                   "pid": None, "matchers": None, "accuracy": None} for d in datasets}
    start = _time.perf_counter()
    with _Cluster(client, workers) as active:
        _drive(active, evaluate_dataset, datasets, {"settings": settings}, rows,
               Progress(len(datasets), progress))
        n_workers = _workers_of(active)
    return EvaluationReport(list(rows.values()), _time.perf_counter() - start, n_workers)


# ---------------------------------------------------------------------------------------------
# The command: python -m hnnstereo.batch

EPILOG = """\
PAIRS.csv (header, then one pair a row; relative paths from PAIRS.csv's folder):
  id,left,right,calib,max_disparity
  teddy,teddy/im2.png,teddy/im6.png,,64          a rectified pair: disparities up to 64 px
  cell-7,cell7/left.png,cell7/right.png,cell7/calib.yml,   a calibrated pair (CAL.yml)
Optional columns ground_truth (left disparity map: PNG/PGM 0 = unknown, or PFM) and
ground_truth_scale (stored value / scale = px; default 1): accuracy in report.json and the
summary (share of matches with ground truth within 1 px, density over the Canny edges).
Writes DIR/<id>/matches.csv (as `hnnstereo match --out`), DIR/<id>/report.json (as --report)
and DIR/manifest.csv (id,status,attempts,seconds,error; status done, failed or skipped).
A failed pair (its worker died, too) is tried once more; a re-run skips the pairs already done.
--scheduler: refused (exit 2) when it does not answer within 5 s.

Match options are the `hnnstereo match` flags, e.g. --max-features 1500 --top-k 8 --no-lr-check
(a flag without a value is on); --preset and --engine as there. Exit status: 0 all pairs done,
1 some failed, 2 bad input (nothing done).

Examples:
  python -m hnnstereo.batch --pairs pairs.csv --out results --workers 2
  dask-scheduler &  dask-worker tcp://HOST:8786 --nthreads 1 --nworkers 4   (on each machine)
  python -m hnnstereo.batch --pairs pairs.csv --out results --scheduler tcp://HOST:8786
"""


def _parser():
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m hnnstereo.batch", epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Match many stereo pairs on a Dask cluster (a local one by default): one "
                    "task a pair, results per pair, a manifest, retries and resume.")
    parser.add_argument("--pairs", required=True, metavar="PAIRS.csv",
                        help="the pairs: id,left,right and calib or max_disparity")
    parser.add_argument("--out", required=True, metavar="DIR", help="the output folder")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="a running Dask scheduler (tcp://host:8786); default: a local "
                             "cluster on this machine")
    parser.add_argument("--workers", type=int, metavar="N",
                        help="local cluster: worker processes, one thread each (default: the "
                             "CPU count)")
    parser.add_argument("--preset", default="hnn-default",
                        help="matcher preset: " + ", ".join(_hnnstereo.preset_names()))
    parser.add_argument("--engine", help="opencl or cpu (default: hnnstereo.Matcher's)")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    return parser


def _match_options(arguments):
    """The remaining arguments -> {name: value}: --name VALUE, --name=VALUE, or --flag (on)."""
    known = set(_hnnstereo.option_names())
    options, index = {}, 0
    while index < len(arguments):
        argument = arguments[index]
        if not argument.startswith("--"):
            raise BatchInputError(f"unexpected argument {argument!r} (match options are --name "
                                  "VALUE)")
        name, has_value, value = argument[2:].partition("=")
        if name not in known:
            raise BatchInputError(f"unknown option --{name} (match options: "
                                  f"{', '.join('--' + n for n in sorted(known) if '_' not in n)})")
        if not has_value and (index + 1 == len(arguments) or arguments[index + 1].startswith("--")):
            value = "true"
        elif not has_value:
            index += 1
            value = arguments[index]
        options[name] = value
        index += 1
    return options


CONNECT_TIMEOUT_S = 5.0  # a scheduler that does not answer in this time is refused


def _connect(address, timeout_s=CONNECT_TIMEOUT_S):
    """A Client of the scheduler at `address`, or BatchInputError with the reason. A tcp://
    address is first tried with a plain socket (a refused or unroutable port is told at once,
    not after the client's retries); the client then gets timeout_s to say hello."""
    import socket

    import dask
    from distributed import Client

    scheme, _, location = address.rpartition("://")
    if scheme in ("", "tcp"):
        host, _, port = location.rpartition(":") if ":" in location else (location, "", "8786")
        try:
            with socket.create_connection((host.strip("[]") or "127.0.0.1", int(port)),
                                          timeout=timeout_s):
                pass
        except ValueError:
            raise BatchInputError(f"--scheduler {address}: not an address like "
                                  "tcp://HOST:8786") from None
        except OSError as error:
            reason = "no answer" if isinstance(error, socket.timeout) else \
                (error.strerror or str(error))
            raise BatchInputError(f"cannot reach the scheduler {address}: {reason} (within "
                                  f"{timeout_s:g} s)") from None
    try:
        # Dask's handshake, bounded here: a peer that accepts and stays silent holds some
        # distributed versions' Client(timeout=...) for ever (2026.8 did).
        _asyncio.run(_asyncio.wait_for(_handshake(address), timeout_s))
        with dask.config.set({"distributed.comm.timeouts.connect": f"{timeout_s}s"}):
            return Client(address, timeout=f"{timeout_s}s")
    except (_asyncio.TimeoutError, TimeoutError):
        raise BatchInputError(f"cannot reach the scheduler {address}: no Dask answer within "
                              f"{timeout_s:g} s") from None
    except (OSError, ValueError) as error:
        raise BatchInputError(f"cannot reach the scheduler {address}: "
                              f"{' '.join(str(error).split())}") from None


async def _handshake(address):
    from distributed.comm import connect

    comm = await connect(address)
    await comm.close()


def main(argv=None):
    """The command; returns the exit status (0 all done, 1 some failed, 2 bad input)."""
    args, rest = _parser().parse_known_args(argv)
    client = None
    try:
        _require_distributed()
        options = _match_options(rest)
        if args.scheduler and args.workers is not None:
            raise BatchInputError("--workers is for the local cluster; --scheduler has its own")
        if args.workers is not None and args.workers < 1:
            raise BatchInputError(f"--workers must be >= 1 (got {args.workers})")
        if args.scheduler:
            client = _connect(args.scheduler)
        report = match_pairs(args.pairs, args.out, client, workers=args.workers,
                             preset=args.preset, engine=args.engine,
                             progress=None if args.quiet else _sys.stderr, **options)
    except (BatchInputError, ImportError) as error:
        print(f"hnnstereo.batch: {error}", file=_sys.stderr)
        return 2
    finally:
        if client is not None:
            client.close()
    print(report.brief())
    return 0 if report.failed == 0 else 1


if __name__ == "__main__":
    # Through the package's module, so that the tasks name hnnstereo.batch.run_pair (importable
    # on the workers), not this __main__.
    from hnnstereo.batch import main as _main

    _sys.exit(_main())
