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

Needs ``pip install hnnstereo[batch]`` (dask distributed); the core module does not import dask.
Workers read the images from their paths, so every worker must see them at the same path (a
shared file system for a remote cluster). Each worker process keeps one Matcher per setting for
its life. A pair whose match fails (an exception, or a KilledWorker after its workers died) is
retried once, then reported failed; the others go on. A re-run skips pairs whose report.json
holds the same inputs and settings (resume).
"""

import csv as _csv
import json as _json
import math as _math
import os as _os
import sys as _sys
import time as _time
import uuid as _uuid

import hnnstereo as _hnnstereo

__all__ = ["BatchInputError", "BatchReport", "Pair", "match_pairs", "read_pairs", "main"]

MANIFEST_COLUMNS = ["id", "status", "attempts", "seconds", "error"]
RESERVED_IDS = {"manifest.csv"}  # DIR/<id> must not be the manifest


class BatchInputError(ValueError):
    """Bad PAIRS.csv, output folder or settings, refused before any work (a one-line reason)."""


class Pair:
    """One pair to match: id (folder name under DIR), image paths, calib path or None, and
    max_disparity (px) or None. Paths are absolute once checked."""

    __slots__ = ("id", "left", "right", "calib", "max_disparity")

    def __init__(self, id, left, right, calib=None, max_disparity=None):
        self.id, self.left, self.right = id, left, right
        self.calib, self.max_disparity = calib, max_disparity

    def inputs(self):
        """The keys report.json records for this pair (resume compares them)."""
        return {"left": self.left, "right": self.right, "calib": self.calib,
                "max_disparity": self.max_disparity}

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


def _max_disparity(text, where):
    try:
        value = float(text)
    except ValueError:
        raise BatchInputError(f"{where}: max_disparity {text!r} is not a number") from None
    if not (value > 0 and _math.isfinite(value)):
        raise BatchInputError(f"{where}: max_disparity must be > 0 px (got {text!r})")
    return value


def _pair_from_row(row, where, base):
    """One PAIRS.csv row (a dict) -> a checked Pair with absolute paths."""
    pair_id = _text(row.get("id"))
    _check_id(pair_id, where)
    paths = {}
    for column in ("left", "right", "calib"):
        text = _text(row.get(column))
        if not text:
            if column == "calib":
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
    return Pair(pair_id, paths["left"], paths["right"], paths.get("calib"), max_disparity)


def check_pairs(rows, base=".", source="pairs"):
    """Rows (dicts or Pairs) -> checked Pairs; relative paths against `base`. Raises
    BatchInputError on a missing column, an empty or duplicate id, an id that is not a folder
    name, a missing file or a bad max_disparity."""
    pairs, seen = [], {}
    for number, row in enumerate(rows, start=1):
        where = f"{source} row {number}"
        if isinstance(row, Pair):
            row = {"id": row.id, "left": row.left, "right": row.right, "calib": row.calib,
                   "max_disparity": row.max_disparity}
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
        inputs.update(_os.path.realpath(p) for p in (pair.left, pair.right, pair.calib) if p)
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
    """Reads and matches one pair on this worker -> (matches float32 N x 6, report dict)."""
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
    return result.matches, result.report


def run_pair(pair, out_dir, settings):
    """The task of one pair on a worker: match, write matches.csv then report.json (each
    atomically; report.json last, so its presence means the pair is complete) -> a dict with
    id, status ("done"/"failed"), seconds, error, n_matches, pid and matchers (this process's
    Matcher count). Never raises for a pair's own failure."""
    start = _time.perf_counter()
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
    except Exception as exception:  # reported in the manifest, retried once by the driver
        status, n_matches = "failed", 0
        error = " ".join(f"{type(exception).__name__}: {exception}".split())
    return {"id": pair.id, "status": status, "error": error, "n_matches": n_matches,
            "seconds": _time.perf_counter() - start, "pid": _os.getpid(),
            "matchers": len(_worker_matchers)}


# ---------------------------------------------------------------------------------------------
# On the client: resume, submit, retry once, progress and the manifest.

def _already_done(pair, out_dir, settings):
    """True when DIR/<id>/report.json (written last) records this pair's inputs and settings."""
    matches_path, report_path = _output_paths(out_dir, pair)
    try:
        with open(report_path, encoding="utf-8") as f:
            report = _json.load(f)
    except (OSError, ValueError):
        return False
    recorded = {key: report.get(key) for key in pair.inputs()}
    return (recorded == pair.inputs() and report.get("batch_settings") == settings
            and _os.path.isfile(matches_path))


def _remove_stale(pair, out_dir):
    """Removes an earlier run's outputs of a pair about to be matched again (report.json first),
    so the folder never holds results the manifest does not describe."""
    for path in reversed(_output_paths(out_dir, pair)):
        if _os.path.exists(path):
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
    """What a batch did: rows (one per pair: id, status, attempts, seconds, error, plus pid and
    matchers for the pairs matched in this run), counts, wall seconds and workers."""

    def __init__(self, rows, seconds, workers, out_dir):
        self.rows, self.seconds, self.workers, self.out_dir = rows, seconds, workers, out_dir
        self.done = sum(r["status"] == "done" for r in rows)
        self.failed = sum(r["status"] == "failed" for r in rows)
        self.skipped = sum(r["status"] == "skipped" for r in rows)

    @property
    def pairs_per_second(self):
        return self.done / self.seconds if self.seconds > 0 else 0.0

    def brief(self):
        text = (f"{self.done} matched, {self.skipped} skipped (done before), {self.failed} failed "
                f"of {len(self.rows)} pairs in {self.seconds:.1f} s on {self.workers} workers: "
                f"{self.pairs_per_second:.2f} pairs/s; manifest "
                f"{_os.path.join(self.out_dir, 'manifest.csv')}")
        for row in [r for r in self.rows if r["status"] == "failed"][:5]:
            text += f"\nfailed {row['id']}: {row['error']}"
        if self.failed > 5:
            text += f"\n... and {self.failed - 5} more failed pairs (manifest.csv)"
        return text


def _submit(client, pairs, out_dir, settings, attempt):
    token = _uuid.uuid4().hex[:8]
    keys = [f"hnnstereo-pair-{token}-{attempt}-{index}" for index in range(len(pairs))]
    futures = client.map(run_pair, pairs, out_dir=out_dir, settings=settings, key=keys,
                         pure=False)
    return dict(zip(futures, pairs))


def _result_of(future, pair):
    """A finished future -> run_pair's dict; a task that raised (a KilledWorker after its
    workers died, a lost worker, a pickling error) becomes a failed result."""
    try:
        return future.result()
    except Exception as exception:
        error = " ".join(f"{type(exception).__name__}: {exception}".split())
        return {"id": pair.id, "status": "failed", "error": error, "n_matches": 0,
                "seconds": None, "pid": None, "matchers": None}


def _drive(client, pairs, out_dir, settings, rows, progress, manifest_interval_s=5.0):
    """Submits the pairs, retries each failed one once, fills `rows` (id -> row) as results come
    and rewrites the manifest every `manifest_interval_s` seconds."""
    from distributed import as_completed

    by_future = _submit(client, pairs, out_dir, settings, attempt=1)
    completed = as_completed(list(by_future))
    finished, failed, last_manifest = 0, 0, _time.perf_counter()
    for future in completed:
        pair = by_future.pop(future)
        result = _result_of(future, pair)
        row = rows[pair.id]
        row.update(status=result["status"], error=result["error"], seconds=result["seconds"],
                   pid=result["pid"], matchers=result["matchers"])
        row["attempts"] += 1
        if result["status"] == "failed" and row["attempts"] < 2:
            retry = _submit(client, [pair], out_dir, settings, attempt=row["attempts"] + 1)
            by_future.update(retry)
            completed.update(list(retry))
        else:
            finished += 1
            failed += result["status"] == "failed"
            progress.update(finished, failed)
        if _time.perf_counter() - last_manifest > manifest_interval_s:
            _write_manifest(out_dir, rows.values())
            last_manifest = _time.perf_counter()
    progress.update(finished, failed, final=True)


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
    max_disparity; relative paths against the current folder). client: a distributed.Client;
    None starts a LocalCluster of `workers` processes (default: the CPU count), one thread each,
    and closes it at the end. preset, engine, match_options: as hnnstereo.match (the
    ``hnnstereo match`` flags; max_disparity is per pair). progress: a stream for the progress
    line (None: silent). Returns a BatchReport. Raises BatchInputError before any work on bad
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
                         "matchers": None}
        if not done_before:
            _remove_stale(pair, out_dir)
            todo.append(pair)
    _write_manifest(out_dir, rows.values())
    return rows, todo


def _run(todo, out_dir, client, workers, settings, rows, progress_stream):
    start = _time.perf_counter()
    cluster = own_client = None
    try:
        if client is None and todo:
            from distributed import Client, LocalCluster

            # No dashboard; the scheduler's own HTTP routes on a free port (the default 8787
            # may be another cluster's).
            cluster = LocalCluster(n_workers=workers or _os.cpu_count() or 1,
                                   threads_per_worker=1, processes=True, dashboard_address=None,
                                   scheduler_kwargs={"dashboard_address": ":0"}, silence_logs=40)
            client = own_client = Client(cluster)
        progress = Progress(len(todo), progress_stream)
        if todo:
            _drive(client, todo, out_dir, settings, rows, progress)
        n_workers = _workers_of(client) if client is not None else 0
    finally:
        _write_manifest(out_dir, rows.values())
        if own_client is not None:
            own_client.close()
            cluster.close()
    return BatchReport(list(rows.values()), _time.perf_counter() - start, n_workers, out_dir)


# ---------------------------------------------------------------------------------------------
# The command: python -m hnnstereo.batch

EPILOG = """\
PAIRS.csv (header, then one pair a row; relative paths from PAIRS.csv's folder):
  id,left,right,calib,max_disparity
  teddy,teddy/im2.png,teddy/im6.png,,64          a rectified pair: disparities up to 64 px
  cell-7,cell7/left.png,cell7/right.png,cell7/calib.yml,   a calibrated pair (CAL.yml)
Writes DIR/<id>/matches.csv (as `hnnstereo match --out`), DIR/<id>/report.json (as --report)
and DIR/manifest.csv (id,status,attempts,seconds,error; status done, failed or skipped).
A failed pair is retried once; a re-run skips the pairs already done.

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


def _connect(address):
    """A Client of the scheduler at `address`, or BatchInputError with the reason."""
    from distributed import Client

    try:
        return Client(address, timeout="30s")
    except (OSError, TimeoutError, ValueError) as error:
        raise BatchInputError(f"cannot reach the scheduler {address}: "
                              f"{' '.join(str(error).split())}") from None


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
