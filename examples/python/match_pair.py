#!/usr/bin/env python3
"""Match a rectified stereo pair with hnnstereo, print a summary, save a disparity scatter plot.

    python3 examples/python/match_pair.py tests/data/middlebury2003_teddy/im2.png \
        tests/data/middlebury2003_teddy/im6.png --max-disparity 64 --plot disparity.png

The plot needs matplotlib (optional: without it the summary is printed and the plot skipped).
"""
import argparse
import sys

import cv2
import numpy as np

import hnnstereo


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("left")
    parser.add_argument("right")
    parser.add_argument("--max-disparity", type=float, default=64)
    parser.add_argument("--calib", help="CAL.yml or calib.txt (else the pair is rectified)")
    parser.add_argument("--plot", help="output PNG: matches at their left position, coloured by disparity")
    args = parser.parse_args()

    left = cv2.imread(args.left, cv2.IMREAD_UNCHANGED)
    right = cv2.imread(args.right, cv2.IMREAD_UNCHANGED)
    if left is None or right is None:
        sys.exit(f"match_pair: cannot read {args.left if left is None else args.right}")
    try:
        result = hnnstereo.match(left, right, max_disparity=args.max_disparity, calib=args.calib)
    except (ValueError, RuntimeError) as error:
        sys.exit(f"match_pair: {error}")

    matches, report = result.matches, result.report
    disparity = matches[:, 0] - matches[:, 2]
    print(f"hnnstereo {hnnstereo.__version__}: {len(matches)} matches from {report['n_left']} left / "
          f"{report['n_right']} right features, engine {report['engine']} on {report['device']}, "
          f"{report['timing_ms']['total']:.1f} ms")
    if len(matches):
        print(f"disparity {disparity.min():.1f} .. {disparity.max():.1f} px, median "
              f"{np.median(disparity):.1f}; confidence median {np.median(matches[:, 5]):.2f}")

    if args.plot:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            print("matplotlib is not installed: no plot")
            return
        figure, axes = plt.subplots(figsize=(8, 6))
        axes.imshow(left[..., ::-1] if left.ndim == 3 else left, cmap="gray")
        points = axes.scatter(matches[:, 0], matches[:, 1], c=disparity, s=3, cmap="viridis")
        figure.colorbar(points, ax=axes, label="disparity (px)")
        axes.set_title(f"{len(matches)} matches")
        figure.savefig(args.plot, dpi=100, bbox_inches="tight")
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
