#!/usr/bin/env python3
"""Fits the matcher's confidence model (vision/stereo_matcher.h, ConfidenceOptions) and measures
how well it ranks, on Middlebury pairs with ground truth.

For every pair it runs `hnnstereo match` (rectified, the pair's disparity range, the default
preset) with --report --report-matches, reads the per-match features of the report (potential_margin,
correlation, correlation_margin, surface_residual, and per radius r of 3, 6, 12, 24 px
neighbours_r and agreement_r = agreeing_r / neighbours_r), labels each match correct when its disparity is within 1 px of
the ground truth (rounded, as `eval` scores), and fits a logistic regression
P(correct) = sigmoid(b + w . features) by Newton's method (IRLS), pooled over the pairs.

It prints the coefficients to paste into ConfidenceOptions, and for each pair - fitted on the
OTHER pairs (leave-one-pair-out), so the figure is one the model has not seen - the error rate of
all matches and of the top 25 / 50 / 75 % by confidence.

    python3 scripts/fit_confidence.py --binary build/hnnstereo --dataset TUNING_DIR --check CHECK_DIR
Needs numpy and Pillow (pip install numpy pillow).
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image

# The fitted default (CensusConfidenceOptions, which weighs the potential margin, the surface
# residual, the agreement at 3 and 6 px and the neighbour counts at 12 and 24 px 0); --features
# picks another set, from these and "agreement_3", "agreement_6", "potential_margin",
# "surface_residual", "neighbours_12", "neighbours_24",
# "relneighbours_R", "relcorrelation", "log_correlation_margin" (docs/accuracy.md).
RADII = (3, 6, 12, 24)
FEATURES = ["correlation", "correlation_margin", "agreement_12", "agreement_24", "neighbours_3",
            "neighbours_6"]


def feature_columns(rows, col, names):
    """The model's inputs from the report's columns (agreement_r = agreeing_r / neighbours_r;
    relneighbours_r = neighbours_r / the pair's median neighbours_r, a scene-relative density;
    relcorrelation = correlation - the pair's median correlation)."""
    out = []
    for name in names:
        if name.startswith("agreement_"):
            r = name.split("_")[1]
            n = rows[:, col["neighbours_" + r]]
            out.append(np.where(n > 0, rows[:, col["agreeing_" + r]] / np.maximum(n, 1), 0.0))
        elif name.startswith("relneighbours_"):
            n = rows[:, col["neighbours_" + name.split("_")[1]]]
            out.append(n / max(float(np.median(n)), 1.0))
        elif name == "log_correlation_margin":
            out.append(np.log(np.maximum(rows[:, col["correlation_margin"]], 0.0) + 0.01))
        elif name == "relcorrelation":
            out.append(rows[:, col["correlation"]] - float(np.median(rows[:, col["correlation"]])))
        else:
            out.append(rows[:, col[name]])
    return np.stack(out, axis=1)


def read_pfm(path):
    with open(path, "rb") as f:
        magic = f.readline().strip()
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    channels = 3 if magic == b"PF" else 1
    data = data.reshape(height, width, channels)[:, :, 0]
    data = np.flipud(data).astype(np.float64)
    data[~np.isfinite(data)] = np.nan
    data[data <= 0] = np.nan
    return data


def find(directory, stem, extensions):
    for ext in extensions:
        path = os.path.join(directory, stem + ext)
        if os.path.isfile(path):
            return path
    return None


def load_pair(directory):
    """(left, right, ground truth disparity with NaN unknown) following vision/middlebury.cc."""
    left, right = find(directory, "im0", [".png"]), find(directory, "im1", [".png"])
    gt = find(directory, "disp0GT", [".pfm"]) or find(directory, "disp0", [".pfm"])
    if left and right and gt:
        return left, right, read_pfm(gt)
    layouts = [("scene1.row3.col3", "scene1.row3.col4", "truedisp.row3.col3", lambda w: 16.0),
               ("view1", "view5", "disp1", lambda w: 3.0 if w < 500 else (2.0 if w < 900 else 1.0)),
               ("im2", "im6", "disp2", None)]
    for l_stem, r_stem, d_stem, scale in layouts:
        left = find(directory, l_stem, [".png", ".ppm", ".pgm"])
        right = find(directory, r_stem, [".png", ".ppm", ".pgm"])
        disp = find(directory, d_stem, [".pgm", ".png"])
        if not (left and right and disp):
            continue
        raw = np.asarray(Image.open(disp).convert("L"), dtype=np.float64)
        width = raw.shape[1]
        if scale is None:  # 2001 (pgm): 8; 2003 (png): 4 below 600 px wide, else 2
            s = 8.0 if disp.endswith(".pgm") else (4.0 if width < 600 else 2.0)
        else:
            s = scale(width)
        gt = raw / s
        gt[raw == 0] = np.nan
        return left, right, gt
    return None


def run_match(binary, left, right, max_disparity, extra, cache=None, name=""):
    if cache and os.path.isfile(os.path.join(cache, name + ".json")):
        with open(os.path.join(cache, name + ".json")) as f:
            return json.load(f)
    with tempfile.TemporaryDirectory() as tmp:
        report = os.path.join(tmp, "r.json")
        cmd = [binary, "match", "--left", left, "--right", right, "--rectified",
               "--max-disparity", str(max_disparity), "--out", os.path.join(tmp, "m.csv"),
               "--report", report, "--report-matches", "--quiet"] + extra
        subprocess.run(cmd, check=True)
        with open(report) as f:
            data = json.load(f)
    if cache:
        os.makedirs(cache, exist_ok=True)
        with open(os.path.join(cache, name + ".json"), "w") as f:
            json.dump(data, f)
    return data


def sgbm_agreement(left, right, max_disparity, uniqueness):
    """Per pixel: StereoSGBM's disparity as `eval` runs it (5x5, MODE_HH, P1 = 8*25, P2 = 32*25,
    disp12MaxDiff 1, speckle 100/2) at this uniqueness ratio; NaN where it gives none. For the
    --sgbm-features experiment (docs/accuracy.md): does a second matcher's opinion rank the
    HNN's matches better? Needs the cv2 module."""
    import cv2
    grey_l = cv2.imread(left, cv2.IMREAD_GRAYSCALE)
    grey_r = cv2.imread(right, cv2.IMREAD_GRAYSCALE)
    n = max(16, 16 * ((max_disparity + 1 + 15) // 16))
    sgbm = cv2.StereoSGBM_create(0, n, 5, 8 * 25, 32 * 25, 1, 63, uniqueness, 100, 2,
                                 cv2.STEREO_SGBM_MODE_HH)
    d = sgbm.compute(grey_l, grey_r).astype(np.float64) / 16.0
    d[d < 0] = np.nan
    return d


def sigmoid(z):
    return 1.0 / (1.0 + np.exp(-z))


def design(X, cap):
    X = X.copy()
    if "potential_margin" in FEATURES:
        k = FEATURES.index("potential_margin")
        X[:, k] = np.minimum(X[:, k], cap)
    return np.hstack([np.ones((X.shape[0], 1)), X])


def fit_logistic(X, y, ridge=1e-3, iterations=50):
    w = np.zeros(X.shape[1])
    for _ in range(iterations):
        p = sigmoid(X @ w)
        gradient = X.T @ (y - p) - ridge * w
        hessian = (X * (p * (1 - p))[:, None]).T @ X + ridge * np.eye(X.shape[1])
        step = np.linalg.solve(hessian, gradient)
        w += step
        if np.max(np.abs(step)) < 1e-8:
            break
    return w


def top_error(confidence, correct, share):
    order = np.argsort(-confidence, kind="stable")
    n = max(1, int(round(share * len(order))))
    return 100.0 * (1.0 - correct[order[:n]].mean())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--binary", default="build/hnnstereo")
    parser.add_argument("--dataset", default="../shared/datasets")
    parser.add_argument("--cap", type=float, default=1e4, help="potential_margin cap")
    parser.add_argument("--match-args", default="", help="extra arguments for match")
    parser.add_argument("--cache", default="", help="keep/reuse the match reports in this folder")
    parser.add_argument("--features", default=",".join(FEATURES),
                        help="comma-separated subset of the features to fit")
    parser.add_argument("--check", default="",
                        help="a folder of pairs scored only: the model fitted on all --dataset "
                             "pairs ranks them (a tuning / check split)")
    parser.add_argument("--sgbm-features", action="store_true",
                        help="experiment: add StereoSGBM's agreement (within 1 px) and validity at "
                             "uniqueness 0 and 10 as features (needs cv2)")
    args = parser.parse_args()
    FEATURES[:] = [f for f in args.features.split(",") if f]
    pairs = {}
    folders = [(args.dataset, n, False) for n in sorted(os.listdir(args.dataset))]
    if args.check:
        folders += [(args.check, n, True) for n in sorted(os.listdir(args.check))]
    checked = {}
    for parent, name, is_check in folders:
        directory = os.path.join(parent, name)
        if not os.path.isdir(directory):
            continue
        loaded = load_pair(directory)
        if loaded is None:
            continue
        left, right, gt = loaded
        max_disparity = int(math.ceil(np.nanmax(gt) / 16.0) * 16)
        print(f"{name}: matching (max disparity {max_disparity})", file=sys.stderr)
        report = run_match(args.binary, left, right, max_disparity, args.match_args.split(),
                           args.cache, name)
        columns = report["matches"]["columns"]
        rows = np.array(report["matches"]["rows"], dtype=np.float64).reshape(-1, len(columns))
        col = {c: i for i, c in enumerate(columns)}
        xl = np.round(rows[:, col["xl"]]).astype(int)
        yl = np.round(rows[:, col["yl"]]).astype(int)
        truth = gt[yl, xl]
        known = np.isfinite(truth)
        disparity = rows[:, col["xl"]] - rows[:, col["xr"]]
        correct = (np.abs(disparity - np.round(truth)) <= 1.0)[known].astype(np.float64)
        X = feature_columns(rows[known], col, FEATURES)
        if args.sgbm_features:
            extra = []
            for uniqueness in (0, 10):
                sgbm = sgbm_agreement(left, right, max_disparity, uniqueness)[yl, xl][known]
                valid = np.isfinite(sgbm)
                agree = valid & (np.abs(np.where(valid, sgbm, 0.0) - disparity[known]) <= 1.0)
                extra += [agree.astype(np.float64), valid.astype(np.float64)]
            X = np.hstack([X, np.stack(extra, axis=1)])
        (checked if is_check else pairs)[name] = (X, correct, rows[known][:, col["confidence"]])
    names = list(pairs)
    X_all = np.vstack([pairs[n][0] for n in names])
    y_all = np.concatenate([pairs[n][1] for n in names])
    w = fit_logistic(design(X_all, args.cap), y_all)
    print("fitted on all pairs (paste into ConfidenceOptions; agreement_r / neighbours_r go to")
    print("w_agreement / w_neighbours in the order of the radii 3, 6, 12, 24):")
    print(f"  bias = {w[0]:.6g}; " + "; ".join(f"w_{f} = {w[i + 1]:.6g}" for i, f in enumerate(FEATURES)))
    print("\n| pair | matches | error all % | top 25 % | top 50 % | top 75 % | top 25 % (current build) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    pooled = {"c": [], "y": [], "b": []}
    for held_out in names:
        train = [n for n in names if n != held_out]
        w_cv = fit_logistic(design(np.vstack([pairs[n][0] for n in train]), args.cap),
                            np.concatenate([pairs[n][1] for n in train]))
        X, y, built = pairs[held_out]
        c = sigmoid(design(X, args.cap) @ w_cv)
        pooled["c"].append(c)
        pooled["y"].append(y)
        pooled["b"].append(built)
        print(f"| {held_out} | {len(y)} | {100 * (1 - y.mean()):.1f} | {top_error(c, y, 0.25):.1f} | "
              f"{top_error(c, y, 0.5):.1f} | {top_error(c, y, 0.75):.1f} | {top_error(built, y, 0.25):.1f} |")
    c, y, b = (np.concatenate(pooled[k]) for k in ("c", "y", "b"))
    print(f"| pooled (leave-one-pair-out) | {len(y)} | {100 * (1 - y.mean()):.1f} | "
          f"{top_error(c, y, 0.25):.1f} | {top_error(c, y, 0.5):.1f} | {top_error(c, y, 0.75):.1f} | "
          f"{top_error(b, y, 0.25):.1f} |")
    if checked:
        print("\n| check pair (fitted on every tuning pair) | matches | error all % | top 25 % | "
              "top 50 % | top 75 % | current build: top 25 % | 50 % | 75 % |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
        for name, (X_check, y_check, built_check) in checked.items():
            c_check = sigmoid(design(X_check, args.cap) @ w)
            print(f"| {name} | {len(y_check)} | {100 * (1 - y_check.mean()):.1f} | "
                  f"{top_error(c_check, y_check, 0.25):.1f} | {top_error(c_check, y_check, 0.5):.1f} | "
                  f"{top_error(c_check, y_check, 0.75):.1f} | " +
                  " | ".join(f"{top_error(built_check, y_check, s):.1f}" for s in (0.25, 0.5, 0.75)) + " |")
    # What a value of the built confidence means (the reports' own column, pooled): what
    # --min-confidence T keeps and how often the kept matches are wrong.
    print("\n| --min-confidence (current build) | matches kept % | error of kept % |")
    print("|---:|---:|---:|")
    for t in (0.5, 0.7, 0.9, 0.95, 0.99):
        kept = b >= t
        error = 100.0 * (1.0 - y[kept].mean()) if kept.any() else float("nan")
        print(f"| {t:g} | {100.0 * kept.mean():.1f} | {error:.2f} |")


if __name__ == "__main__":
    main()
