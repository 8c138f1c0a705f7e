#!/usr/bin/env python3
"""What the matcher's confident wrong matches are, and whether anything the pipeline could add
would fix them, measured on Middlebury pairs with ground truth (docs/accuracy.md, "What limits
the 75 % density").

It reads the `match --report` files that `scripts/fit_confidence.py --cache DIR` keeps (the
default preset) and takes, per pair, the wrong matches (more than 1 px off, as `eval` scores) at
*non-occluded* pixels among the top SHARE (default 85 %) of matches by the built confidence - the
errors the acceptance's 75 % density still keeps. For those it prints:

- `truth in 4 peaks`: the true disparity (+-1 px) is among the 4 best local maxima of ZNCC 7 x 7
  along the row, i.e. among the candidates the network chooses from (hnn-default: K = 4 peaks);
- `shiftable 5x5`: the same with the best of 5 windows of 5 x 5 (centred, shifted 2 px
  left/right/up/down) - windows that may avoid crossing the depth edge;
- `SGBM right` / `SGBM agrees`: StereoSGBM as `eval` runs it (uniqueness 0, left-right check)
  is within 1 px of the truth / of the HNN's own disparity there.

With `--no-lr-cache DIR` (reports of `fit_confidence.py --match-args=--no-lr-check --cache
DIR`) it also measures the left-right check as a confidence feature instead of a filter: the
reverse ZNCC search's agreement (<= 1 px) and distance join the model's features, fitted
leave-one-pair-out, and the error at 25 / 50 / 75 % of the left Canny (50/150) pixels with
ground truth is compared with the default (check as a filter). Occluded pixels count as wrong
there, as in fit_confidence.py.

With `--side-features` it measures a confidence feature aimed at those errors: at a depth edge
seen in the decoded matches (the median disparities of the neighbours within 8 px on the two
sides of the pixel's gradient line differ by 2 px or more), whether the match took the nearer
side's disparity while the pixel's own grey level looks like the farther side (a pixel beside an
occluding contour that the contour dragged along). `--sgbm-features`: StereoSGBM's validity and
agreement at uniqueness 10 and 60 (a second matcher's opinion). `--zncc-features`: ZNCC 7 x 7
at the match, its margin and its own winner's agreement (a second data term's opinion for the
census network). `--vertex-features`: the ZNCC
parabola's vertex offset and sharpness at the match (an integer disparity whose truth may lie a
pixel away). Each is scored leave-one-pair-out as `eval` scores: error over the kept
non-occluded matches at 25 / 50 / 75 % of the left Canny pixels with ground truth.

    python3 scripts/fit_confidence.py --cache /tmp/fc
    python3 scripts/fit_confidence.py --cache /tmp/fc_nolr --match-args=--no-lr-check
    build/hnnstereo eval --dataset ../shared/datasets --out /tmp/e.json --presets hnn-default
    python3 scripts/confident_errors.py --cache /tmp/fc --no-lr-cache /tmp/fc_nolr --side-features \
        --sgbm-features --vertex-features --eval-json /tmp/e.json
Needs numpy, Pillow and cv2 (python3-opencv).
"""
import argparse
import json
import math
import os
import sys

import cv2
import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fit_confidence as fc  # noqa: E402  (pair loader, features, logistic fit)

# The right-view ground truth of the sets without an occlusion mask (as vision/middlebury.cc).
RIGHT_TRUTH = {"disp6.pgm": 8.0, "disp6.png": 4.0, "disp5.png": None}


def visible(directory, gt):
    """Non-occluded left pixels: the set's mask, else a 1 px left-right check of the two
    ground-truth maps (as `eval`)."""
    for mask, test in (("nonocc.png", lambda m: m > 128), ("mask0nocc.png", lambda m: m == 255)):
        path = os.path.join(directory, mask)
        if os.path.isfile(path):
            return test(np.asarray(Image.open(path).convert("L")))
    for stem, scale in RIGHT_TRUTH.items():
        path = os.path.join(directory, stem)
        if not os.path.isfile(path):
            continue
        raw = np.asarray(Image.open(path).convert("L"), dtype=np.float64)
        if scale is None:  # 2005/2006 thirds: scale by width as the left map
            scale = 3.0 if raw.shape[1] < 500 else (2.0 if raw.shape[1] < 900 else 1.0)
        right = np.where(raw > 0, raw / scale, np.nan)
        ys, xs = np.nonzero(np.isfinite(gt))
        xr = np.round(xs - gt[ys, xs]).astype(int)
        inside = (xr >= 0) & (xr < gt.shape[1])
        agree = np.zeros(len(xs), bool)
        agree[inside] = np.abs(right[ys[inside], xr[inside]] - gt[ys[inside], xs[inside]]) <= 1.0
        out = np.zeros(gt.shape, bool)
        out[ys, xs] = agree
        return out
    return np.isfinite(gt)


def read_report(cache, name):
    with open(os.path.join(cache, name + ".json")) as f:
        report = json.load(f)
    columns = report["matches"]["columns"]
    rows = np.array(report["matches"]["rows"], dtype=np.float64).reshape(-1, len(columns))
    return rows, {c: i for i, c in enumerate(columns)}


def zncc_profile(left, right, x, y, max_disparity, dx, dy, half):
    """ZNCC of the (2 half + 1)^2 left window centred at (x + dx, y + dy) against the right row,
    indexed by disparity 0..max_disparity (-1 where the window leaves the image)."""
    cx, cy = x + dx, y + dy
    height, width = left.shape
    out = np.full(max_disparity + 1, -1.0)
    if cy - half < 0 or cy + half >= height or cx - half < 0 or cx + half >= width:
        return out
    x0 = max(0, cx - max_disparity - half)
    strip = right[cy - half:cy + half + 1, x0:cx + half + 1]
    if strip.shape[1] < 2 * half + 1:
        return out
    score = cv2.matchTemplate(strip, left[cy - half:cy + half + 1, cx - half:cx + half + 1],
                              cv2.TM_CCOEFF_NORMED)[0]
    disparity = cx - (x0 + half + np.arange(len(score)))
    out[disparity] = score
    return out


def best_peaks(score, k):
    """Disparities of the k highest local maxima of a ZNCC profile."""
    n = len(score)
    peaks = [d for d in range(n) if score[d] > -1 and (d == 0 or score[d] >= score[d - 1]) and
             (d == n - 1 or score[d] >= score[d + 1])]
    return np.array(sorted(peaks, key=lambda d: -score[d])[:k])


def candidate_table(pairs, cache, share):
    print(f"Wrong matches at non-occluded pixels among the top {100 * share:.0f} % by confidence:\n")
    print("| pair | wrong | truth in 4 peaks (7x7) | shiftable 5x5 | SGBM right | SGBM agrees |")
    print("|---|---:|---:|---:|---:|---:|")
    shifts = [(0, 0), (2, 0), (-2, 0), (0, 2), (0, -2)]
    for name, (directory, left_path, right_path, gt, max_disparity) in pairs.items():
        rows, col = read_report(cache, name)
        xl = np.round(rows[:, col["xl"]]).astype(int)
        yl = np.round(rows[:, col["yl"]]).astype(int)
        truth = gt[yl, xl]
        keep = np.isfinite(truth) & visible(directory, gt)[yl, xl]
        rows, xl, yl, truth = rows[keep], xl[keep], yl[keep], np.round(truth[keep])
        disparity = rows[:, col["xl"]] - rows[:, col["xr"]]
        confidence = rows[:, col["confidence"]]
        top = np.zeros(len(rows), bool)
        top[np.argsort(-confidence, kind="stable")[:int(share * len(rows))]] = True
        wrong = np.where(top & (np.abs(disparity - truth) > 1.0))[0]
        left = cv2.imread(left_path, cv2.IMREAD_GRAYSCALE).astype(np.float32)
        right = cv2.imread(right_path, cv2.IMREAD_GRAYSCALE).astype(np.float32)
        sgbm = fc.sgbm_agreement(left_path, right_path, max_disparity, 0)[yl, xl]
        in_peaks = in_shiftable = 0
        for i in wrong:
            centred = zncc_profile(left, right, xl[i], yl[i], max_disparity, 0, 0, 3)
            shiftable = np.max([zncc_profile(left, right, xl[i], yl[i], max_disparity, dx, dy, 2)
                                for dx, dy in shifts], axis=0)
            in_peaks += np.any(np.abs(best_peaks(centred, 4) - truth[i]) <= 1)
            in_shiftable += np.any(np.abs(best_peaks(shiftable, 4) - truth[i]) <= 1)
        s = sgbm[wrong]
        valid = np.isfinite(s)
        right_share = np.mean(valid & (np.abs(np.where(valid, s, 0) - truth[wrong]) <= 1))
        agree_share = np.mean(valid & (np.abs(np.where(valid, s, 0) - disparity[wrong]) <= 1))
        n = max(1, len(wrong))
        print(f"| {name} | {len(wrong)} | {100 * in_peaks / n:.0f} % | {100 * in_shiftable / n:.0f} % | "
              f"{100 * right_share:.0f} % | {100 * agree_share:.0f} % |")


def reverse_check(left, right, rows, col, max_disparity):
    """The left-right check's reverse search (vision/matcher_presets.cc): the best left x for each
    right point by ZNCC 7 x 7 over the disparity range; returns |best left x - xl| (0 at borders)."""
    distance = np.zeros(len(rows))
    for i, (xr, y, xl) in enumerate(zip(rows[:, col["xr"]], rows[:, col["yl"]], rows[:, col["xl"]])):
        x, y = int(round(xr)), int(round(y))
        if y - 3 < 0 or y + 3 >= left.shape[0] or x - 3 < 0 or x + 3 >= left.shape[1]:
            continue
        strip = left[y - 3:y + 4, x - 3:min(left.shape[1], x + max_disparity + 4)]
        if strip.shape[1] < 7:
            continue
        score = cv2.matchTemplate(strip, right[y - 3:y + 4, x - 3:x + 4], cv2.TM_CCOEFF_NORMED)[0]
        distance[i] = abs(x + int(np.argmax(score)) - xl)
    return distance


def soft_check_table(pairs, cache, no_lr_cache):
    def dataset(report_cache, with_check_features):
        out = {}
        for name, (directory, left_path, right_path, gt, max_disparity) in pairs.items():
            rows, col = read_report(report_cache, name)
            xl = np.round(rows[:, col["xl"]]).astype(int)
            yl = np.round(rows[:, col["yl"]]).astype(int)
            truth = gt[yl, xl]
            known = np.isfinite(truth)
            rows = rows[known]
            disparity = rows[:, col["xl"]] - rows[:, col["xr"]]
            correct = (np.abs(disparity - np.round(truth[known])) <= 1.0).astype(np.float64)
            X = fc.feature_columns(rows, col, fc.FEATURES)
            if with_check_features:
                left = cv2.imread(left_path, cv2.IMREAD_GRAYSCALE).astype(np.float32)
                right = cv2.imread(right_path, cv2.IMREAD_GRAYSCALE).astype(np.float32)
                distance = reverse_check(left, right, rows, col, max_disparity)
                X = np.hstack([X, (distance <= 1.0)[:, None], np.minimum(distance, 10.0)[:, None]])
            out[name] = (X, correct)
        return out

    def leave_one_out(data):
        result = {}
        for held_out in data:
            train = [n for n in data if n != held_out]
            w = fc.fit_logistic(fc.design(np.vstack([data[n][0] for n in train]), 1e4),
                                np.concatenate([data[n][1] for n in train]))
            X, y = data[held_out]
            result[held_out] = (fc.sigmoid(fc.design(X, 1e4) @ w), y)
        return result

    filtered = leave_one_out(dataset(cache, False))
    soft = leave_one_out(dataset(no_lr_cache, True))
    print("\nLeft-right check as a filter (default) or as a confidence feature: error % of the top "
          "matches by confidence at a density of the left Canny pixels with ground truth "
          "(leave-one-pair-out; occluded pixels count as wrong):\n")
    print("| pair | edge pixels | filter: 25 / 50 / 75 % | feature: 25 / 50 / 75 % |")
    print("|---|---:|---|---|")
    pooled = {"filter": np.zeros((3, 2)), "feature": np.zeros((3, 2))}
    for name, (directory, left_path, _, gt, _) in pairs.items():
        edges = cv2.Canny(cv2.imread(left_path, cv2.IMREAD_GRAYSCALE), 50, 150) > 0
        n = int(np.sum(edges & np.isfinite(gt)))
        cells = []
        for tag, result in (("filter", filtered), ("feature", soft)):
            confidence, y = result[name]
            order = np.argsort(-confidence, kind="stable")
            figures = []
            for row, density in enumerate((0.25, 0.5, 0.75)):
                k = int(density * n)
                if k > len(y):
                    figures.append("n/a")
                    continue
                wrong = float(np.sum(1.0 - y[order[:k]]))
                pooled[tag][row] += (wrong, k)
                figures.append(f"{100 * wrong / k:.2f}")
            cells.append(" / ".join(figures))
        print(f"| {name} | {n} | {cells[0]} | {cells[1]} |")
    print("| pooled over the pairs that reach it | | " + " | ".join(
        " / ".join(f"{100 * w / max(k, 1):.2f}" for w, k in pooled[tag])
        for tag in ("filter", "feature")) + " |")


def side_features(grey, xl, yl, disparity, radius=8, offset=2.0):
    """Per match: [at a depth edge, share of the way from the farther to the nearer side's
    disparity the match took, where the pixel's grey level lies from the farther (0) to the
    nearer (1) side's, took-nearer x looks-farther]; zeros away from depth edges."""
    smooth = cv2.GaussianBlur(grey, (3, 3), 0)
    gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3)
    points = np.stack([xl, yl], axis=1).astype(np.float64)
    cells = {}
    for i, (x, y) in enumerate(zip(xl // radius, yl // radius)):
        cells.setdefault((x, y), []).append(i)
    height, width = grey.shape
    out = np.zeros((len(xl), 4))
    for i in range(len(xl)):
        x, y = int(xl[i]), int(yl[i])
        normal = np.array([gx[y, x], gy[y, x]], dtype=np.float64)
        norm = np.linalg.norm(normal)
        if norm < 1e-3:
            continue
        normal /= norm
        cx, cy = x // radius, y // radius
        near = [j for dx in (-1, 0, 1) for dy in (-1, 0, 1) for j in cells.get((cx + dx, cy + dy), [])
                if j != i]
        near = np.array([j for j in near if np.hypot(*(points[j] - points[i])) <= radius], dtype=int)
        if len(near) < 4:
            continue
        across = (points[near] - points[i]) @ normal
        side_a, side_b = near[across < -1.5], near[across > 1.5]
        if len(side_a) < 2 or len(side_b) < 2:
            continue
        d_a, d_b = np.median(disparity[side_a]), np.median(disparity[side_b])
        if abs(d_a - d_b) < 2.0:
            continue

        def grey_at(px, py):
            px, py = min(max(px, 0.0), width - 1.001), min(max(py, 0.0), height - 1.001)
            return float(cv2.getRectSubPix(grey, (1, 1), (float(px), float(py)))[0, 0])

        grey_a = grey_at(x - offset * normal[0], y - offset * normal[1])
        grey_b = grey_at(x + offset * normal[0], y + offset * normal[1])
        (d_near, grey_near), (d_far, grey_far) = sorted(
            [(d_a, grey_a), (d_b, grey_b)], key=lambda side: -side[0])
        looks = (float(grey[y, x]) - grey_far) / (grey_near - grey_far) \
            if abs(grey_near - grey_far) > 4.0 else 0.5
        looks = min(max(looks, -0.5), 1.5)
        took = min(max((disparity[i] - d_far) / (d_near - d_far), -0.5), 1.5)
        out[i] = [1.0, took, looks, took * (1.0 - looks)]
    return out


def density_feature_table(pairs, cache, title, extra, eval_json=""):
    """A candidate confidence feature scored as `eval` scores the ranking: fitted
    leave-one-pair-out with and without the columns `extra(name, pair, rows, col, xl, yl,
    disparity)` returns, error % (more than 1 px off the ground truth) of the kept non-occluded
    matches at 25 / 50 / 75 % of the left Canny (50/150) pixels with ground truth: `eval`'s own
    count (`n_edges_with_truth`, which leaves out the detector's border) from `eval_json`, else
    every Canny pixel with ground truth."""
    data = {False: {}, True: {}}
    edges_n = {}
    counted = {}
    if eval_json:
        with open(eval_json) as f:
            counted = {p["name"]: p["n_edges_with_truth"] for p in json.load(f)["pairs"]}
    for name, pair in pairs.items():
        directory, left_path, _, gt, _ = pair
        rows, col = read_report(cache, name)
        xl = np.round(rows[:, col["xl"]]).astype(int)
        yl = np.round(rows[:, col["yl"]]).astype(int)
        disparity = rows[:, col["xl"]] - rows[:, col["xr"]]
        truth = gt[yl, xl]
        known = np.isfinite(truth)
        correct = (np.abs(disparity - truth) <= 1.0)[known].astype(np.float64)
        seen = visible(directory, gt)[yl, xl][known]
        X = fc.feature_columns(rows[known], col, fc.FEATURES)
        more = extra(name, pair, rows, col, xl, yl, disparity)[known]
        data[False][name] = (X, correct, seen)
        data[True][name] = (np.hstack([X, more]), correct, seen)
        grey = cv2.imread(left_path, cv2.IMREAD_GRAYSCALE)
        edges_n[name] = counted.get(name, int(np.sum((cv2.Canny(grey, 50, 150) > 0) &
                                                     np.isfinite(gt))))
    print(f"\n{title}: error % of the kept non-occluded matches at 25 / 50 / 75 % of the left "
          "Canny pixels with ground truth (leave-one-pair-out; pooled over the pairs that reach "
          "the density):\n")
    print("| pair | without: 25 / 50 / 75 % | with: 25 / 50 / 75 % |")
    print("|---|---|---|")
    densities = (0.25, 0.5, 0.75)
    pooled = {False: np.zeros((3, 2)), True: np.zeros((3, 2))}
    cells = {name: [] for name in pairs}
    for with_extra in (False, True):
        for held_out in pairs:
            train = [n for n in pairs if n != held_out]
            w = fc.fit_logistic(fc.design(np.vstack([data[with_extra][n][0] for n in train]), 1e4),
                                np.concatenate([data[with_extra][n][1] for n in train]))
            X, y, seen = data[with_extra][held_out]
            order = np.argsort(-fc.sigmoid(fc.design(X, 1e4) @ w), kind="stable")
            figures = []
            for row, density in enumerate(densities):
                k = int(density * edges_n[held_out])
                if k > len(y):
                    figures.append("n/a")
                    continue
                kept = order[:k][seen[order[:k]]]
                wrong = float(np.sum(1.0 - y[kept]))
                pooled[with_extra][row] += (wrong, len(kept))
                figures.append(f"{100 * wrong / max(len(kept), 1):.2f}")
            cells[held_out].append(" / ".join(figures))
    for name in pairs:
        print(f"| {name} | {cells[name][0]} | {cells[name][1]} |")
    print("| pooled | " + " | ".join(" / ".join(f"{100 * w / max(k, 1):.2f}" for w, k in pooled[s])
                                   for s in (False, True)) + " |")


def side_columns(name, pair, rows, col, xl, yl, disparity):
    grey = cv2.imread(pair[1], cv2.IMREAD_GRAYSCALE)
    return side_features(grey.astype(np.float32), xl, yl, disparity)


def sgbm_columns(name, pair, rows, col, xl, yl, disparity):
    """StereoSGBM (as `eval` runs it) at uniqueness 10 and 60: valid here, and within 1 px of
    the match's disparity."""
    _, left_path, right_path, _, max_disparity = pair
    out = []
    for uniqueness in (10, 60):
        d = fc.sgbm_agreement(left_path, right_path, max_disparity, uniqueness)[yl, xl]
        valid = np.isfinite(d)
        out += [valid, valid & (np.abs(np.where(valid, d, 0.0) - disparity) <= 1.0)]
    return np.stack(out, axis=1).astype(np.float64)


def grey_pair(pair):
    """The pair's left and right images as float32 grey levels, and its disparity range."""
    _, left_path, right_path, _, max_disparity = pair
    return (cv2.imread(left_path, cv2.IMREAD_GRAYSCALE).astype(np.float32),
            cv2.imread(right_path, cv2.IMREAD_GRAYSCALE).astype(np.float32), max_disparity)


def vertex_columns(name, pair, rows, col, xl, yl, disparity):
    """The parabola through ZNCC 7 x 7 at the match's disparity d and d +- 1: how far its vertex
    lies from d (0-1 px) and how sharp it is - does an integer disparity whose truth may lie a
    pixel away rank lower?"""
    left, right, max_disparity = grey_pair(pair)
    d = np.round(disparity).astype(int)
    score = np.zeros((len(d), 3))
    for i in range(len(d)):
        profile = zncc_profile(left, right, xl[i], yl[i], max_disparity, 0, 0, 3)
        for k, step in enumerate((-1, 0, 1)):
            score[i, k] = profile[d[i] + step] if 0 <= d[i] + step <= max_disparity else -1.0
    curvature = score[:, 0] - 2.0 * score[:, 1] + score[:, 2]
    sharp = curvature < -1e-6
    offset = np.where(sharp, 0.5 * (score[:, 0] - score[:, 2]) / np.where(sharp, curvature, 1.0), 0.0)
    return np.stack([np.minimum(np.abs(offset), 1.0), -curvature], axis=1)


def zncc_columns(name, pair, rows, col, xl, yl, disparity):
    """A second data term's opinion, for a network built on the census one: ZNCC 7 x 7 at the
    match's disparity, its lead over the best ZNCC more than 1 px away, and whether ZNCC's own
    winner-take-all lies within 1 px of the match."""
    left, right, max_disparity = grey_pair(pair)
    d = np.round(disparity).astype(int)
    out = np.zeros((len(d), 3))
    for i in range(len(d)):
        profile = zncc_profile(left, right, xl[i], yl[i], max_disparity, 0, 0, 3)
        at = profile[d[i]] if 0 <= d[i] <= max_disparity else -1.0
        away = np.abs(np.arange(len(profile)) - d[i]) > 1
        best_away = profile[away].max() if away.any() else -1.0
        out[i] = (at, at - best_away, float(abs(int(np.argmax(profile)) - d[i]) <= 1))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="../shared/datasets")
    parser.add_argument("--cache", required=True, help="fit_confidence.py --cache folder (default preset)")
    parser.add_argument("--no-lr-cache", default="", help="the same with --match-args=--no-lr-check")
    parser.add_argument("--side-features", action="store_true",
                        help="also measure the depth-edge side feature as a confidence input")
    parser.add_argument("--eval-json", default="",
                        help="EVAL.json of `eval` on the same pairs: its edge counts as the densities' base")
    parser.add_argument("--sgbm-features", action="store_true",
                        help="rank also by StereoSGBM's validity and agreement at uniqueness 10 and 60")
    parser.add_argument("--vertex-features", action="store_true",
                        help="rank also by the ZNCC parabola's vertex offset and sharpness")
    parser.add_argument("--zncc-features", action="store_true",
                        help="rank also by ZNCC 7 x 7 at the match, its margin and its own winner's "
                             "agreement (a second data term's opinion for the census network)")
    parser.add_argument("--share", type=float, default=0.85, help="top share of matches by confidence")
    args = parser.parse_args()
    pairs = {}
    for name in sorted(os.listdir(args.dataset)):
        directory = os.path.join(args.dataset, name)
        loaded = fc.load_pair(directory) if os.path.isdir(directory) else None
        if loaded is None or not os.path.isfile(os.path.join(args.cache, name + ".json")):
            continue
        left, right, gt = loaded
        pairs[name] = (directory, left, right, gt, int(math.ceil(np.nanmax(gt) / 16.0) * 16))
    candidate_table(pairs, args.cache, args.share)
    if args.no_lr_cache:
        soft_check_table(pairs, args.cache, args.no_lr_cache)
    if args.side_features:
        density_feature_table(pairs, args.cache, "The depth-edge side feature", side_columns, args.eval_json)
    if args.sgbm_features:
        density_feature_table(pairs, args.cache, "StereoSGBM at uniqueness 10 and 60 (valid, agrees)",
                              sgbm_columns, args.eval_json)
    if args.vertex_features:
        density_feature_table(pairs, args.cache, "The ZNCC parabola's vertex offset and sharpness",
                              vertex_columns, args.eval_json)
    if args.zncc_features:
        density_feature_table(pairs, args.cache, "ZNCC 7 x 7 at the match, its margin, its winner agrees",
                              zncc_columns, args.eval_json)


if __name__ == "__main__":
    main()
