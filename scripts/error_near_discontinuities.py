#!/usr/bin/env python3
"""Where the matcher's wrong matches lie: near depth discontinuities, and with a disparity that
a neighbouring surface has (window "fattening"), measured on Middlebury pairs with ground truth.

For every pair it runs `hnnstereo match` (rectified, the pair's disparity range, the default
preset; or reads the reports kept by `scripts/fit_confidence.py --cache DIR`), labels each match
correct when its disparity is within 1 px of the ground truth (rounded, as `eval` scores), and
prints, for the wrong and the correct matches, the share that lie near a depth discontinuity
(the ground truth spans more than STEP px of disparity within the WINDOW x WINDOW square around
the pixel), and the share of wrong matches whose disparity lies within 1 px of the ground
truth's range in that square (the disparity of a neighbouring surface).

    python3 scripts/error_near_discontinuities.py --cache /tmp/fc
Needs numpy and Pillow (pip install numpy pillow).
"""
import argparse
import math
import os
import sys

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fit_confidence  # noqa: E402  (the pair loader and the match runner)


def window_extremes(gt, window):
    """Per pixel, the largest and smallest known ground-truth disparity in the window."""
    pad = window // 2
    high = np.pad(np.where(np.isfinite(gt), gt, -np.inf), pad, constant_values=-np.inf)
    low = np.pad(np.where(np.isfinite(gt), gt, np.inf), pad, constant_values=np.inf)
    return (sliding_window_view(high, (window, window)).max(axis=(2, 3)),
            sliding_window_view(low, (window, window)).min(axis=(2, 3)))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--binary", default="build/hnnstereo")
    parser.add_argument("--dataset", default="../shared/datasets")
    parser.add_argument("--cache", default="", help="keep/reuse the match reports in this folder")
    parser.add_argument("--window", type=int, default=9, help="square side (px), odd")
    parser.add_argument("--step", type=float, default=3.0, help="disparity span (px) that counts as a discontinuity")
    args = parser.parse_args()
    print(f"| pair | wrong | wrong near a discontinuity | wrong with a neighbour's disparity "
          f"| correct near a discontinuity |")
    print("|---|---:|---:|---:|---:|")
    for name in sorted(os.listdir(args.dataset)):
        directory = os.path.join(args.dataset, name)
        loaded = fit_confidence.load_pair(directory) if os.path.isdir(directory) else None
        if loaded is None:
            continue
        left, right, gt = loaded
        max_disparity = int(math.ceil(np.nanmax(gt) / 16.0) * 16)
        report = fit_confidence.run_match(args.binary, left, right, max_disparity, [], args.cache, name)
        columns = report["matches"]["columns"]
        rows = np.array(report["matches"]["rows"], dtype=np.float64).reshape(-1, len(columns))
        col = {c: i for i, c in enumerate(columns)}
        xl = np.round(rows[:, col["xl"]]).astype(int)
        yl = np.round(rows[:, col["yl"]]).astype(int)
        disparity = rows[:, col["xl"]] - rows[:, col["xr"]]
        truth = gt[yl, xl]
        known = np.isfinite(truth)
        wrong = known & (np.abs(disparity - np.round(np.nan_to_num(truth))) > 1.0)
        correct = known & ~wrong
        high, low = window_extremes(gt, args.window)
        near = (high[yl, xl] - low[yl, xl]) > args.step
        neighbour = (disparity >= low[yl, xl] - 1.0) & (disparity <= high[yl, xl] + 1.0)
        print(f"| {name} | {wrong.sum()} | {100 * near[wrong].mean():.0f} % "
              f"| {100 * neighbour[wrong].mean():.0f} % | {100 * near[correct].mean():.0f} % |")


if __name__ == "__main__":
    main()
