"""hnnstereo.batch on a local Dask cluster of 2 worker processes: every pair matched as one process
matches it, a worker killed midway loses no pair, resume, one retry, bad input refused."""

import csv
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import cv2
import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

import hnnstereo  # noqa: E402
import hnnstereo.batch as batch  # noqa: E402

SOURCE_DIR = os.environ.get("HNNSTEREO_SOURCE_DIR",
                            os.path.join(os.path.dirname(__file__), "..", ".."))
CLI = os.environ.get("HNNSTEREO_BINARY", "")
TEDDY = os.path.join(SOURCE_DIR, "tests", "data", "middlebury2003_teddy")
N_PAIRS = 20
# Debian's distributed 2022.12 on tornado 6.2 (its event loop set-up), not ours to fix.
pytestmark = pytest.mark.filterwarnings("ignore:make_current is deprecated:DeprecationWarning")
CROP = (200, 166)  # width, height: small crops keep a pair well under a second


@pytest.fixture(scope="module")
def pairs_csv(tmp_path_factory):
    """N_PAIRS rectified pairs: the same window of Teddy's im2/im6 at different offsets."""
    folder = tmp_path_factory.mktemp("pairs")
    left = cv2.imread(os.path.join(TEDDY, "im2.png"), cv2.IMREAD_UNCHANGED)
    right = cv2.imread(os.path.join(TEDDY, "im6.png"), cv2.IMREAD_UNCHANGED)
    width, height = CROP
    rows = ["id,left,right,max_disparity"]
    for index in range(N_PAIRS):
        x0 = (index * 37) % (left.shape[1] - width + 1)
        y0 = (index * 23) % (left.shape[0] - height + 1)
        for side, image in (("l", left), ("r", right)):
            cv2.imwrite(str(folder / f"p{index:02d}_{side}.png"),
                        image[y0:y0 + height, x0:x0 + width])
        rows.append(f"p{index:02d},p{index:02d}_l.png,p{index:02d}_r.png,{40 + index % 3 * 4}")
    (folder / "pairs.csv").write_text("\n".join(rows) + "\n")
    return folder / "pairs.csv"


@pytest.fixture(scope="module")
def expected(pairs_csv):
    """id -> matches.csv text of the single-process hnnstereo.match."""
    texts = {}
    for pair in batch.read_pairs(pairs_csv):
        result = hnnstereo.match(cv2.imread(pair.left, cv2.IMREAD_UNCHANGED),
                                 cv2.imread(pair.right, cv2.IMREAD_UNCHANGED),
                                 max_disparity=pair.max_disparity)
        texts[pair.id] = batch.matches_csv(result.matches)
    return texts


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=40,
                                       scheduler_kwargs={"dashboard_address": ":0"})
    with distributed.Client(cluster) as dask_client:
        yield dask_client
    cluster.close()


def manifest(out_dir):
    with open(out_dir / "manifest.csv", newline="") as f:
        return list(csv.DictReader(f))


def assert_every_pair_once(out_dir, expected, status="done"):
    rows = manifest(out_dir)
    assert sorted(row["id"] for row in rows) == sorted(expected)  # each id once, none lost
    for row in rows:
        assert row["status"] == status, row
        folder = out_dir / row["id"]
        # A worker killed while writing may leave a hidden .tmp-* file, never a visible one.
        visible = sorted(name for name in os.listdir(folder) if not name.startswith("."))
        assert visible == ["matches.csv", "report.json"], row
        assert (folder / "matches.csv").read_text() == expected[row["id"]], row["id"]
        report = json.loads((folder / "report.json").read_text())
        assert report["n_matches"] == expected[row["id"]].count("\n") - 1
        assert report["left"].endswith(f"{row['id']}_l.png")
    return rows


def test_two_workers_match_every_pair_as_one_process_does(pairs_csv, expected, client, tmp_path):
    report = batch.match_pairs(pairs_csv, tmp_path / "out", client)
    assert (report.done, report.failed, report.skipped) == (N_PAIRS, 0, 0)
    rows = assert_every_pair_once(tmp_path / "out", expected)
    assert all(row["attempts"] == "1" and row["error"] == "" for row in rows)
    # One Matcher per worker process for its life, not one per pair.
    assert {row["matchers"] for row in report.rows} == {1}
    assert len({row["pid"] for row in report.rows}) == 2


def test_matches_csv_is_the_cli_file(pairs_csv, expected, tmp_path):
    if not CLI:
        pytest.skip("HNNSTEREO_BINARY is not set (ctest sets it)")
    pair = batch.read_pairs(pairs_csv)[0]
    subprocess.run([CLI, "match", "--left", pair.left, "--right", pair.right, "--rectified",
                    "--max-disparity", str(pair.max_disparity), "--out", str(tmp_path / "m.csv"),
                    "--quiet"], check=True)
    assert (tmp_path / "m.csv").read_text() == expected[pair.id]


def running_pid(folder):
    """The worker pid of a run of the pair in `folder` that has begun and not ended (its
    DIR/<id>/.running-<key>-<pid> marker), or None."""
    for marker in folder.glob(".running-*") if folder.exists() else []:
        return int(marker.name.rsplit("-", 1)[1])
    return None


def kill_workers_running(folder, times, deadline_s=240):
    """SIGKILLs the worker process running the pair in `folder`, `times` times (each a new run)
    -> the pids killed."""
    killed, deadline = [], time.monotonic() + deadline_s
    while len(killed) < times and time.monotonic() < deadline:
        pid = running_pid(folder)
        if pid is not None and pid not in killed:
            try:
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
            except ProcessLookupError:  # it ended (its run too) just now
                pass
        time.sleep(0.005)
    return killed


def in_thread(function):
    outcome = {}
    thread = threading.Thread(target=lambda: outcome.update(value=function()))
    thread.start()
    return thread, outcome


def test_a_worker_killed_midway_loses_and_repeats_no_pair(pairs_csv, expected, client, tmp_path):
    """The fixture's scheduler reruns the killed pair by itself (dask's allowed-failures): the
    rerun still counts as that pair's second attempt."""
    out_dir = tmp_path / "out"
    run, outcome = in_thread(lambda: batch.match_pairs(pairs_csv, out_dir, client))
    killed = kill_workers_running(out_dir / "p08", 1)
    run.join(300)
    assert not run.is_alive() and len(killed) == 1
    assert outcome["value"].done == N_PAIRS
    rows = assert_every_pair_once(out_dir, expected)
    assert {row["id"]: row["attempts"] for row in rows if row["attempts"] != "1"} == {"p08": "2"}
    client.wait_for_workers(2, timeout=60)  # the nanny restarts it for the tests after


def test_a_pair_whose_worker_dies_twice_is_reported_failed(pairs_csv, expected, tmp_path):
    """The local cluster of match_pairs: a worker death is an attempt, retried once, then
    reported; the other pairs are done once each."""
    out_dir = tmp_path / "out"
    run, outcome = in_thread(lambda: batch.match_pairs(pairs_csv, out_dir, workers=2))
    killed = kill_workers_running(out_dir / "p03", 2)
    run.join(300)
    assert not run.is_alive() and len(killed) == 2
    report = outcome["value"]
    assert (report.done, report.failed) == (N_PAIRS - 1, 1)
    rows = {row["id"]: row for row in manifest(out_dir)}
    failed = rows.pop("p03")
    assert (failed["status"], failed["attempts"]) == ("failed", "2")
    assert "KilledWorker" in failed["error"]
    assert not any(name for name in os.listdir(out_dir / "p03") if not name.startswith(".tmp"))
    assert all(row["status"] == "done" and row["attempts"] == "1" for row in rows.values())
    for pair_id in rows:
        assert (out_dir / pair_id / "matches.csv").read_text() == expected[pair_id]


def test_a_rerun_skips_the_pairs_done(pairs_csv, expected, client, tmp_path):
    out_dir = tmp_path / "out"
    batch.match_pairs(pairs_csv, out_dir, client)
    kept = (out_dir / "p03" / "matches.csv").stat().st_mtime_ns
    os.remove(out_dir / "p05" / "report.json")  # as a run killed before p05 was complete
    report = batch.match_pairs(pairs_csv, out_dir, client)
    assert (report.done, report.skipped, report.failed) == (1, N_PAIRS - 1, 0)
    statuses = {row["id"]: row["status"] for row in manifest(out_dir)}
    assert statuses.pop("p05") == "done"
    assert set(statuses.values()) == {"skipped"}
    assert (out_dir / "p03" / "matches.csv").stat().st_mtime_ns == kept
    assert (out_dir / "p05" / "matches.csv").read_text() == expected["p05"]
    # Other settings: every pair is matched again.
    report = batch.match_pairs(pairs_csv, out_dir, client, top_k=4)
    assert (report.done, report.skipped) == (N_PAIRS, 0)
    # The command's --top-k 4 is that setting: all skipped (and no cluster started for none).
    assert batch.main(["--pairs", str(pairs_csv), "--out", str(out_dir), "--top-k", "4"]) == 0
    assert {row["status"] for row in manifest(out_dir)} == {"skipped"}


def test_a_failed_pair_is_retried_once_and_reported(pairs_csv, client, tmp_path):
    (tmp_path / "broken.png").write_text("not an image")
    rows = [{"id": "good", "left": str(pairs_csv.parent / "p00_l.png"),
             "right": str(pairs_csv.parent / "p00_r.png"), "max_disparity": "40"},
            {"id": "broken", "left": str(tmp_path / "broken.png"),
             "right": str(pairs_csv.parent / "p00_r.png"), "max_disparity": "40"}]
    report = batch.match_pairs(rows, tmp_path / "out", client)
    assert (report.done, report.failed) == (1, 1)
    by_id = {row["id"]: row for row in manifest(tmp_path / "out")}
    assert by_id["good"]["status"] == "done" and by_id["good"]["attempts"] == "1"
    assert by_id["broken"]["status"] == "failed" and by_id["broken"]["attempts"] == "2"
    assert "cannot read the left image" in by_id["broken"]["error"]
    assert not (tmp_path / "out" / "broken" / "report.json").exists()
    assert "failed broken: ValueError: cannot read the left image" in report.brief()


def run_command(*arguments):
    return subprocess.run([sys.executable, "-m", "hnnstereo.batch", *map(str, arguments)],
                          capture_output=True, text=True, timeout=300)


def test_the_command_shows_progress_and_a_summary(pairs_csv, expected, tmp_path):
    small = pairs_csv.parent / "three_pairs.csv"  # next to the images: relative paths
    small.write_text("\n".join(pairs_csv.read_text().splitlines()[:4]) + "\n")
    done = run_command("--pairs", small, "--out", tmp_path / "out", "--workers", "2")
    assert done.returncode == 0, done.stderr
    assert "3/3 pairs, " in done.stderr and "pairs/s, ETA" in done.stderr
    assert "Warning" not in done.stderr, done.stderr
    assert "3 matched, 0 skipped (done before), 0 failed of 3 pairs" in done.stdout
    for pair_id in ("p00", "p01", "p02"):
        assert (tmp_path / "out" / pair_id / "matches.csv").read_text() == expected[pair_id]


def test_help_teaches_the_formats():
    done = run_command("--help")
    assert done.returncode == 0
    for text in ("PAIRS.csv", "max_disparity", "manifest.csv", "--scheduler", "--top-k",
                 "python -m hnnstereo.batch --pairs"):
        assert text in done.stdout, text


def write_pairs(path, text):
    path.write_text(text)
    return path


def refused(capsys, *arguments):
    """batch.main in this process (no cluster starts for refused input) -> its one-line stderr."""
    status = batch.main([str(a) for a in arguments])
    stderr = capsys.readouterr().err
    assert status == 2, stderr
    assert stderr.count("\n") == 1 and stderr.startswith("hnnstereo.batch: "), stderr
    return stderr


BAD_PAIRS = [
    ("no-right", "id,left,max_disparity\na,{l},40\n", "the header must name id, left, right"),
    ("no-geometry", "id,left,right\na,{l},{r}\n", "calib or max_disparity"),
    ("duplicate", "id,left,right,max_disparity\na,{l},{r},40\na,{l},{r},40\n",
     "duplicate id 'a' (first at row 1)"),
    ("missing-file", "id,left,right,max_disparity\na,{l},nope.png,40\n",
     "right 'nope.png' is not a file"),
    ("separator", "id,left,right,max_disparity\nx/y,{l},{r},40\n", "is not a folder name"),
    ("dot-dot", "id,left,right,max_disparity\n..,{l},{r},40\n", "is not a folder name"),
    ("empty-id", "id,left,right,max_disparity\n,{l},{r},40\n", "empty id"),
    ("bad-disparity", "id,left,right,max_disparity\na,{l},{r},-3\n", "max_disparity must be > 0"),
    ("no-disparity", "id,left,right,calib,max_disparity\na,{l},{r},,\n",
     "neither calib nor max_disparity"),
    ("extra-field", "id,left,right,max_disparity\na,{l},{r},40,9\n", "more fields than"),
    ("no-rows", "id,left,right,max_disparity\n", "no pairs"),
]


@pytest.mark.parametrize("text, reason", [case[1:] for case in BAD_PAIRS],
                         ids=[case[0] for case in BAD_PAIRS])
def test_bad_pairs_csv_is_refused_before_any_work(pairs_csv, tmp_path, capsys, text, reason):
    left, right = pairs_csv.parent / "p00_l.png", pairs_csv.parent / "p00_r.png"
    path = write_pairs(tmp_path / "pairs.csv", text.format(l=left, r=right))
    assert reason in refused(capsys, "--pairs", path, "--out", tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_missing_pairs_csv_is_refused(tmp_path, capsys):
    assert "cannot read" in refused(capsys, "--pairs", tmp_path / "nope.csv", "--out", tmp_path)


def test_an_unwritable_out_is_refused(pairs_csv, tmp_path, capsys):
    (tmp_path / "file").write_text("")
    assert "cannot write to --out" in refused(capsys, "--pairs", pairs_csv, "--out",
                                              tmp_path / "file" / "out")


def test_outputs_never_overwrite_an_input(pairs_csv, tmp_path, capsys):
    out_dir = tmp_path / "out"
    (out_dir / "a").mkdir(parents=True)
    image = (pairs_csv.parent / "p00_l.png").read_bytes()
    (out_dir / "a" / "matches.csv").write_bytes(image)  # an input where an output would go
    path = write_pairs(tmp_path / "pairs.csv", "id,left,right,max_disparity\n"
                       f"a,{out_dir / 'a' / 'matches.csv'},{pairs_csv.parent / 'p00_r.png'},40\n")
    assert "is an input: choose another --out" in refused(capsys, "--pairs", path, "--out", out_dir)
    assert (out_dir / "a" / "matches.csv").read_bytes() == image
    assert not (out_dir / "manifest.csv").exists()


def test_bad_options_are_refused_before_any_work(pairs_csv, tmp_path, capsys):
    cases = [(["--no-such-option", "3"], "unknown option --no-such-option"),
             (["--top-k", "many"], "top-k"),
             (["--max-disparity", "40"], "max_disparity is per pair"),
             (["--preset", "nope"], "unknown preset 'nope'"),
             (["--engine", "gpu"], "unknown engine 'gpu'"),
             (["--scheduler", "tcp://127.0.0.1:9", "--workers", "2"], "--workers is for the local"),
             (["--workers", "0"], "--workers must be >= 1")]
    for arguments, reason in cases:
        assert reason in refused(capsys, "--pairs", pairs_csv, "--out", tmp_path / "out",
                                 *arguments), arguments
        assert not (tmp_path / "out").exists()


# ---- Accuracy: evaluate() and the ground_truth column, against `hnnstereo eval` -------------

def write_pfm(path, values):
    """A grey little-endian PFM, rows bottom-to-top (the Middlebury 2014 format)."""
    with open(path, "wb") as f:
        f.write(f"Pf\n{values.shape[1]} {values.shape[0]}\n-1\n".encode())
        f.write(np.flipud(values).astype("<f4").tobytes())


@pytest.fixture(scope="module")
def datasets(tmp_path_factory):
    """Two sets: Teddy 2003 as vendored (PNG / 4, occlusions by left-right check) and a
    Middlebury 2014 layout made from a band of it (PFM ground truth, +inf unknown, a mask)."""
    folder = tmp_path_factory.mktemp("sets")
    teddy = folder / "teddy2003"
    teddy.mkdir()
    for name in ("im2.png", "im6.png", "disp2.png", "disp6.png"):
        (teddy / name).write_bytes(open(os.path.join(TEDDY, name), "rb").read())
    band = folder / "band2014"
    band.mkdir()
    rows = slice(90, 260)
    for source, target in (("im2.png", "im0.png"), ("im6.png", "im1.png")):
        image = cv2.imread(os.path.join(TEDDY, source), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(band / target), image[rows])
    stored = cv2.imread(os.path.join(TEDDY, "disp2.png"), cv2.IMREAD_UNCHANGED)[rows]
    disparity = np.where(stored > 0, stored / 4.0, np.inf).astype(np.float32)
    write_pfm(band / "disp0GT.pfm", disparity)
    # 255 visible, 128 occluded (2014's level: only 255 counts), here every 7th column.
    mask = np.full(stored.shape, 255, np.uint8)
    mask[:, ::7] = 128
    cv2.imwrite(str(band / "mask0nocc.png"), mask)
    return folder


@pytest.fixture(scope="module")
def cli_eval(datasets, tmp_path_factory):
    """`hnnstereo eval` over both sets: set name -> its hnn-default figures, and the overall."""
    if not CLI:
        pytest.skip("HNNSTEREO_BINARY is not set (ctest sets it)")
    out = tmp_path_factory.mktemp("eval") / "eval.json"
    subprocess.run([CLI, "eval", "--dataset", str(datasets), "--presets", "hnn-default",
                    "--no-baselines", "--out", str(out), "--quiet"], check=True, timeout=600)
    data = json.loads(out.read_text())
    figures = {p["name"]: p["methods"][0] for p in data["pairs"]}
    figures["overall"] = data["overall"][0]
    return figures


COMPARED = ["n_matches", "n_with_truth", "n_nonoccluded", "n_occluded", "n_edges_with_truth"]


def test_evaluate_gives_the_figures_of_hnnstereo_eval(datasets, cli_eval, client):
    report = batch.evaluate(datasets, client)
    assert report.failed == 0
    by_name = {os.path.basename(row["id"]): row["accuracy"] for row in report.rows}
    assert sorted(by_name) == ["band2014", "teddy2003"]
    assert by_name["band2014"]["occlusion_source"] == "mask"
    assert by_name["teddy2003"]["occlusion_source"] == "left-right check"
    assert by_name["band2014"]["n_occluded"] > 0  # the mask's occluded columns were read
    for name, accuracy in list(by_name.items()) + [("overall", report.overall)]:
        expected_figures = cli_eval[name]
        assert ({k: accuracy[k] for k in COMPARED}
                == {k: expected_figures[k] for k in COMPARED}), name
        for key in ("precision_1px", "precision_2px", "density"):
            assert accuracy[key] == pytest.approx(expected_figures[key], abs=1e-12), (name, key)
    assert "within 1 px" in report.brief() and "(overall)" in report.brief()


def test_evaluate_refuses_a_folder_without_sets(tmp_path):
    with pytest.raises(batch.BatchInputError, match="is not a Middlebury set and holds none"):
        batch.evaluate([tmp_path])


def test_ground_truth_column_scores_each_pair(datasets, cli_eval, client, tmp_path):
    """Teddy with its left ground truth (no mask: every known pixel counts as visible, so the
    matches within 1 px are eval's visible and occluded ones together)."""
    teddy = datasets / "teddy2003"
    pairs = tmp_path / "pairs.csv"
    pairs.write_text("id,left,right,max_disparity,ground_truth,ground_truth_scale\n"
                     f"teddy,{teddy / 'im2.png'},{teddy / 'im6.png'},64,{teddy / 'disp2.png'},4\n"
                     f"plain,{teddy / 'im2.png'},{teddy / 'im6.png'},64,,\n")
    report = batch.match_pairs(pairs, tmp_path / "out", client)
    assert (report.done, report.failed) == (2, 0)
    accuracy = json.loads((tmp_path / "out" / "teddy" / "report.json").read_text())["accuracy"]
    assert "accuracy" not in json.loads((tmp_path / "out" / "plain" / "report.json").read_text())
    eval_teddy = cli_eval["teddy2003"]
    for key in ("n_matches", "n_with_truth", "n_edges_with_truth"):
        assert accuracy[key] == eval_teddy[key], key
    assert accuracy["n_nonoccluded"] == eval_teddy["n_with_truth"]
    assert accuracy["density"] == pytest.approx(eval_teddy["density"], abs=1e-12)
    correct = (eval_teddy["precision_1px"] * eval_teddy["n_nonoccluded"]
               + eval_teddy["occluded_precision_1px"] * eval_teddy["n_occluded"])
    assert accuracy["correct_1px"] == round(correct)
    assert report.accuracy["n_pairs"] == 1 and report.accuracy["correct_1px"] == round(correct)
    line = report.brief().splitlines()[1]
    assert line.startswith("accuracy on 1 pairs with ground truth: ") and "within 1 px" in line
    # A re-run skips both pairs and still gives the accuracy (from report.json).
    again = batch.match_pairs(pairs, tmp_path / "out", client)
    assert again.skipped == 2 and again.accuracy["correct_1px"] == round(correct)


@pytest.mark.parametrize("columns, reason", [
    ("a,{l},{r},40,{l},0", "ground_truth_scale must be > 0"),
    ("a,{l},{r},40,,4", "ground_truth_scale without ground_truth"),
    ("a,{l},{r},40,nope.png,4", "ground_truth 'nope.png' is not a file"),
], ids=["zero-scale", "scale-alone", "missing-truth"])
def test_bad_ground_truth_is_refused(pairs_csv, tmp_path, capsys, columns, reason):
    left, right = pairs_csv.parent / "p00_l.png", pairs_csv.parent / "p00_r.png"
    path = write_pairs(tmp_path / "pairs.csv", "id,left,right,max_disparity,ground_truth,"
                       "ground_truth_scale\n" + columns.format(l=left, r=right) + "\n")
    assert reason in refused(capsys, "--pairs", path, "--out", tmp_path / "out")


# ---- --scheduler: an address that does not answer is refused at once ------------------------

def test_an_unreachable_scheduler_is_refused_quickly(pairs_csv, tmp_path, capsys):
    with socket.socket() as closed:  # a port nobody listens on
        closed.bind(("127.0.0.1", 0))
        port = closed.getsockname()[1]
    start = time.monotonic()
    stderr = refused(capsys, "--pairs", pairs_csv, "--out", tmp_path / "out", "--scheduler",
                     f"tcp://127.0.0.1:{port}")
    assert time.monotonic() - start < 3, stderr
    assert f"cannot reach the scheduler tcp://127.0.0.1:{port}: " in stderr
    assert not (tmp_path / "out").exists()


def test_a_silent_scheduler_is_refused_within_the_connect_timeout(pairs_csv, tmp_path, capsys):
    with socket.socket() as silent:  # accepts connections, never answers dask's hello
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        start = time.monotonic()
        stderr = refused(capsys, "--pairs", pairs_csv, "--out", tmp_path / "out", "--scheduler",
                         f"tcp://127.0.0.1:{silent.getsockname()[1]}")
    assert time.monotonic() - start < batch.CONNECT_TIMEOUT_S + 10, stderr
    assert "cannot reach the scheduler" in stderr
