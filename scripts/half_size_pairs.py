#!/usr/bin/env python3
"""Half-size copies of the Middlebury pairs in a folder, for checking settings on pairs they were
not chosen on (docs/accuracy.md, "Half-size pairs").

Every set `fit_confidence.py` can load is sampled at half size twice - from pixel (0, 0) and from
(1, 1), two different samplings - with cv2.INTER_AREA for the images, the ground truth taken at
the sampled pixels and halved, and the non-occluded mask of `eval` (the set's own mask, else a
1 px left-right check of the two ground-truth maps) sampled the same way. Each copy is written in
the Middlebury 2014 layout, which `eval` reads: im0.png, im1.png, disp0GT.pfm (little-endian,
+inf = unknown) and mask0nocc.png (255 non-occluded, 128 occluded, 0 unknown).

    python3 scripts/half_size_pairs.py --dataset ../shared/datasets --out half-size
    build/hnnstereo eval --dataset half-size --out half.json --markdown half.md --presets hnn-default
Needs numpy, OpenCV's Python bindings and Pillow (as fit_confidence.py).
"""
import argparse
import math
import os
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import confident_errors  # noqa: E402
import fit_confidence  # noqa: E402


def write_pfm(path, disparity):
    height, width = disparity.shape
    with open(path, "wb") as f:
        f.write(b"Pf\n%d %d\n-1\n" % (width, height))
        values = np.where(np.isfinite(disparity), disparity, np.inf).astype("<f4")
        f.write(np.flipud(values).tobytes())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="../shared/datasets")
    parser.add_argument("--out", required=True, help="folder for the half-size sets (created)")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    for name in sorted(os.listdir(args.dataset)):
        directory = os.path.join(args.dataset, name)
        loaded = fit_confidence.load_pair(directory) if os.path.isdir(directory) else None
        if loaded is None:
            continue
        left_path, right_path, truth = loaded
        left = cv2.imread(left_path, cv2.IMREAD_COLOR)
        right = cv2.imread(right_path, cv2.IMREAD_COLOR)
        visible = confident_errors.visible(directory, truth)
        for phase in (0, 1):
            half_left = cv2.resize(left[phase:, phase:], None, fx=0.5, fy=0.5,
                                   interpolation=cv2.INTER_AREA)
            half_right = cv2.resize(right[phase:, phase:], None, fx=0.5, fy=0.5,
                                    interpolation=cv2.INTER_AREA)
            rows, cols = half_left.shape[:2]
            half_truth = truth[phase::2, phase::2][:rows, :cols] / 2.0
            half_visible = visible[phase::2, phase::2][:rows, :cols]
            out = os.path.join(args.out, f"middlebury2014_half{phase}_{name.split('_')[-1]}")
            os.makedirs(out, exist_ok=True)
            cv2.imwrite(os.path.join(out, "im0.png"), half_left)
            cv2.imwrite(os.path.join(out, "im1.png"), half_right)
            mask = np.where(np.isfinite(half_truth), np.where(half_visible, 255, 128), 0)
            cv2.imwrite(os.path.join(out, "mask0nocc.png"), mask.astype(np.uint8))
            write_pfm(os.path.join(out, "disp0GT.pfm"), half_truth)
            top = np.nanmax(half_truth)
            print(f"{out}: {cols} x {rows}, disparities up to {top:.1f} "
                  f"(eval searches 0..{int(math.ceil(top / 16.0) * 16)})")


if __name__ == "__main__":
    main()
