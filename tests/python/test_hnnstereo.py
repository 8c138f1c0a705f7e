"""The Python module against the CLI: same matches for Teddy, the report's keys, bad input."""

import csv
import json
import os
import subprocess
import threading

import cv2
import numpy as np
import pytest

import hnnstereo

SOURCE_DIR = os.environ.get("HNNSTEREO_SOURCE_DIR",
                            os.path.join(os.path.dirname(__file__), "..", ".."))
CLI = os.environ.get("HNNSTEREO_BINARY", "")
TEDDY = os.path.join(SOURCE_DIR, "tests", "data", "middlebury2003_teddy")
REPORT_KEYS = ["engine", "device", "n_left", "n_right", "n_neurons", "n_connections",
               "iterations", "energy_initial", "energy_final", "timing_ms"]


@pytest.fixture(scope="module")
def teddy():
    left = cv2.imread(os.path.join(TEDDY, "im2.png"), cv2.IMREAD_UNCHANGED)
    right = cv2.imread(os.path.join(TEDDY, "im6.png"), cv2.IMREAD_UNCHANGED)
    assert left is not None and right is not None
    return left, right


def run_cli(*arguments):
    if not CLI:
        pytest.skip("HNNSTEREO_BINARY is not set (ctest sets it)")
    done = subprocess.run([CLI, *arguments], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    return done


@pytest.fixture(scope="module")
def cli_teddy(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli")
    run_cli("match", "--left", os.path.join(TEDDY, "im2.png"), "--right",
            os.path.join(TEDDY, "im6.png"), "--rectified", "--max-disparity", "64",
            "--out", str(out / "m.csv"), "--report", str(out / "r.json"), "--quiet")
    with open(out / "m.csv") as f:
        rows = list(csv.reader(f))
    with open(out / "r.json") as f:
        report = json.load(f)
    return rows, report


def csv_rows(matches):
    """The rows of MATCHES.csv as the CLI formats them (vision/match_io.cc)."""
    return [["%.3f" % m[0], "%.3f" % m[1], "%.3f" % m[2], "%.3f" % m[3], "%.6f" % m[4],
             "%.6f" % m[5]] for m in matches.tolist()]


def test_version_is_the_cmake_project_version():
    with open(os.path.join(SOURCE_DIR, "CMakeLists.txt")) as f:
        text = f.read()
    assert f"project(hnnstereo VERSION {hnnstereo.__version__} " in text


def test_match_gives_the_cli_matches_for_teddy(teddy, cli_teddy):
    rows, cli_report = cli_teddy
    result = hnnstereo.match(*teddy, max_disparity=64)
    assert result.matches.dtype == np.float32
    assert result.matches.shape == (len(rows) - 1, 6)
    assert rows[0] == ["xl", "yl", "xr", "yr", "activation", "confidence"]
    assert csv_rows(result.matches) == rows[1:]
    for key in REPORT_KEYS:
        assert key in result.report, key
    for key in ["features", "candidates", "network", "weights", "solve", "decode", "total"]:
        assert key in result.report["timing_ms"], key
    assert set(cli_report) - {"left", "right"} == set(result.report)
    assert result.report["n_matches"] == cli_report["n_matches"]
    assert result.report["preset"] == "hnn-default"


def test_grey_input_matches_like_bgr(teddy):
    left, right = teddy
    bgr = hnnstereo.match(left, right, max_disparity=64)
    grey = hnnstereo.match(cv2.cvtColor(left, cv2.COLOR_BGR2GRAY),
                           cv2.cvtColor(right, cv2.COLOR_BGR2GRAY), max_disparity=64)
    np.testing.assert_array_equal(bgr.matches, grey.matches)


def test_options_are_the_cli_flags(teddy, tmp_path):
    left, right = teddy
    result = hnnstereo.match(left, right, max_disparity=48, max_features=800, top_k=6,
                             no_lr_check=True, engine="cpu")
    assert result.report["engine"] == "cpu"
    assert result.report["left_right_check"] is False
    run_cli("match", "--left", os.path.join(TEDDY, "im2.png"), "--right",
            os.path.join(TEDDY, "im6.png"), "--rectified", "--max-disparity", "48",
            "--max-features", "800", "--top-k", "6", "--no-lr-check", "--engine", "cpu",
            "--out", str(tmp_path / "m.csv"), "--quiet")
    with open(tmp_path / "m.csv") as f:
        rows = list(csv.reader(f))
    assert csv_rows(result.matches) == rows[1:]


def test_bad_input_raises_with_one_line_reasons(teddy):
    left, right = teddy
    cases = [
        (ValueError, lambda: hnnstereo.match(left.astype(np.float32), right), "uint8 or uint16"),
        (ValueError, lambda: hnnstereo.match(left, right[:100]), "differ in size"),
        (ValueError, lambda: hnnstereo.match(left[:, :, :2], right[:, :, :2]), "channels"),
        (ValueError, lambda: hnnstereo.match(left, right, no_such_option=1), "no-such-option"),
        (ValueError, lambda: hnnstereo.match(left, right, preset="nope"), "unknown preset 'nope'"),
        (ValueError, lambda: hnnstereo.match(left, right, engine="gpu"), "unknown engine 'gpu'"),
        (ValueError, lambda: hnnstereo.match(left, right, top_k="many"), "top-k"),
        (RuntimeError, lambda: hnnstereo.load_calibration("/nonexistent/cal.yml"), "cal.yml"),
        (RuntimeError, lambda: hnnstereo.match(np.zeros((64, 64), np.uint8),
                                               np.full((64, 64), 9, np.uint8), max_disparity=32),
         "no features"),
        # Refused as `hnnstereo match` refuses them (one setup check for both).
        (ValueError, lambda: hnnstereo.match(left, left), "left and right are identical"),
        (ValueError, lambda: hnnstereo.match(left, right, max_disparity=0), "--max-disparity"),
        (ValueError, lambda: hnnstereo.match(None, right), "the left image is None"),
        (ValueError, lambda: hnnstereo.match(left, "im6.png"), "must be a numpy array"),
    ]
    for error, call, reason in cases:
        with pytest.raises(error) as raised:
            call()
        message = str(raised.value)
        assert reason in message
        assert "\n" not in message


def test_the_gil_is_released_while_matching(teddy):
    left, right = teddy
    matcher = hnnstereo.Matcher(engine="cpu", max_features=3000)
    ticks = []
    worker = threading.Thread(target=lambda: matcher.match(left, right, max_disparity=64))
    worker.start()
    while worker.is_alive():
        ticks.append(1)
        worker.join(0.001)
    assert len(ticks) > 5


def test_pick_gives_the_cli_objects(tmp_path):
    scene = tmp_path / "scene"
    run_cli("render", "--seed", "3", "--objects", "2", "--out", str(scene))
    run_cli("pick", "--left", str(scene / "left.png"), "--right", str(scene / "right.png"),
            "--calib", str(scene / "calib.yml"), "--out", str(tmp_path / "objects.json"),
            "--quiet")
    with open(tmp_path / "objects.json") as f:
        cli_objects = json.load(f)["objects"]
    calib = hnnstereo.load_calibration(scene / "calib.yml")
    assert calib.P1.shape == (3, 4)
    objects = hnnstereo.pick(cv2.imread(str(scene / "left.png"), cv2.IMREAD_UNCHANGED),
                             cv2.imread(str(scene / "right.png"), cv2.IMREAD_UNCHANGED), calib)
    assert len(objects) == len(cli_objects) > 0
    for mine, theirs in zip(objects, cli_objects):
        for key in ["id", "centroid", "height", "yaw_deg", "points"]:
            assert mine[key] == theirs[key], key


def test_module_holds_neither_the_renderer_nor_the_evaluation():
    # The dynamic symbols: the installed module is stripped of the others.
    nm = subprocess.run(["nm", "-D", "-C", hnnstereo._hnnstereo.__file__], capture_output=True,
                        text=True)
    if nm.returncode != 0:
        pytest.skip("nm cannot read the module: " + nm.stderr.strip())
    assert "vision::SensePositions" in nm.stdout  # the check reads the module's symbols
    for symbol in ("vision::RenderScene", "vision::EvaluatePair", "vision::CompareWithTruth"):
        assert symbol not in nm.stdout
