#!/usr/bin/env python3
"""The widened development set of issue 42: variants of real pairs and rendered scenes, in a
tuning part and a check part (docs/accuracy.md, "Tuning and check pairs").

Writes OUT/tune and OUT/check, every pair in the Middlebury 2014 layout that `eval` reads
(im0.png, im1.png, disp0GT.pfm with +inf unknown, mask0nocc.png: 255 non-occluded, 128 occluded,
0 unknown):

- each real pair of --dataset (any layout `fit_confidence.py` loads; linked, not copied) goes to
  `check` when its name contains one of --check-names, else to `tune`, with its variants beside it:
  `geometric` - a crop of 80 % of each side at an offset drawn from --seed, then scaled by 0.75
  (images cv2.INTER_AREA, ground truth at the sampled pixels, times 0.75);
  `radiometric` - the right camera 25 % darker with gamma 1.2, both images with Gaussian noise of
  sigma 4 grey levels (independent per image and pixel);
- rendered scenes (640 x 480, --scenes per kind and part, seeds from --seed): `lowtex` (plain
  surfaces whose only inner edges are faint printed marks, slanted background), `repeated`
  (stripes and grids of 6-16 px period along the epipolar lines on a textured background: the
  repeated facade) and `outdoor` (a ground plane receding to a
  horizon, a plain sky, facades with window grids, cameras of different exposure), drawn in a
  640 x 480 frame and rendered at --render-scale times it. Surfaces are planes d = a x + b y + c
  in the left image; each view is rendered with 2 x 2 samples per pixel,
  the nearer surface (larger disparity) wins, and a left pixel is non-occluded when the right
  view sees the same surface at x - d.

    python3 scripts/dev_set.py --dataset ../shared/datasets --out dev
    build/hnnstereo eval --dataset dev/tune --out tune.json --presets hnn-default
    build/hnnstereo eval --dataset dev/check --out check.json --presets hnn-default

Never choose a setting on dev/check. Refuses an --out that exists and is not empty, and one inside
--dataset. Needs numpy, OpenCV's Python bindings and Pillow (as fit_confidence.py).
"""
import argparse
import os
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import confident_errors  # noqa: E402
import fit_confidence  # noqa: E402
from half_size_pairs import write_pfm  # noqa: E402

WIDTH, HEIGHT = 640, 480  # the frame scenes are drawn in (design pixels)
SCALE = 1.0  # rendered images are SCALE times the frame (--render-scale)
TEXTURE_SCALE = 4  # texture maps hold 4 x 4 texels per left-image pixel


def write_pair(out, left, right, truth, visible):
    """One pair in the 2014 layout; `truth` NaN where unknown, `visible` the non-occluded mask."""
    os.makedirs(out)
    cv2.imwrite(os.path.join(out, "im0.png"), left)
    cv2.imwrite(os.path.join(out, "im1.png"), right)
    mask = np.where(np.isfinite(truth), np.where(visible, 255, 128), 0).astype(np.uint8)
    cv2.imwrite(os.path.join(out, "mask0nocc.png"), mask)
    write_pfm(os.path.join(out, "disp0GT.pfm"), truth)


# --- variants of real pairs ---------------------------------------------------------------------

def geometric(left, right, truth, visible, rng):
    rows, cols = truth.shape
    crop_rows, crop_cols = int(rows * 0.8), int(cols * 0.8)
    y0 = int(rng.integers(0, rows - crop_rows + 1))
    x0 = int(rng.integers(0, cols - crop_cols + 1))
    window = (slice(y0, y0 + crop_rows), slice(x0, x0 + crop_cols))
    # The right image keeps the same columns: a crop of a rectified pair shifts both views alike,
    # so the disparities do not change.
    scale = 0.75
    size = (int(round(crop_cols * scale)), int(round(crop_rows * scale)))
    images = [cv2.resize(image[window], size, interpolation=cv2.INTER_AREA) for image in (left, right)]
    ys = np.clip(np.round((np.arange(size[1]) + 0.5) / scale - 0.5).astype(int), 0, crop_rows - 1)
    xs = np.clip(np.round((np.arange(size[0]) + 0.5) / scale - 0.5).astype(int), 0, crop_cols - 1)
    sampled = truth[window][np.ix_(ys, xs)] * scale
    return images[0], images[1], sampled, visible[window][np.ix_(ys, xs)]


def radiometric(left, right, truth, visible, rng):
    def noisy(image):
        return np.clip(image + rng.normal(0.0, 4.0, image.shape), 0, 255)

    darker = 255.0 * (0.75 * right.astype(np.float64) / 255.0) ** 1.2
    return (noisy(left.astype(np.float64)).astype(np.uint8), noisy(darker).astype(np.uint8),
            truth, visible)


VARIANTS = {"geometric": geometric, "radiometric": radiometric}


# --- rendered scenes ----------------------------------------------------------------------------

def smooth_noise(rng, cells, octaves=4, persistence=0.55):
    """Fractal value noise on the texture grid, in [-1, 1] (sum of bicubically upsampled octaves)."""
    size = (WIDTH * TEXTURE_SCALE, HEIGHT * TEXTURE_SCALE)
    total = np.zeros((size[1], size[0]), np.float32)
    amplitude, norm = 1.0, 0.0
    for octave in range(octaves):
        n = cells * 2 ** octave
        grid = rng.uniform(-1, 1, (max(2, n * HEIGHT // WIDTH), n)).astype(np.float32)
        total += amplitude * cv2.resize(grid, size, interpolation=cv2.INTER_CUBIC)
        norm += amplitude
        amplitude *= persistence
    return np.clip(total / norm, -1, 1)


def texel_grid():
    ys, xs = np.mgrid[0:HEIGHT * TEXTURE_SCALE, 0:WIDTH * TEXTURE_SCALE].astype(np.float32)
    return (xs + 0.5) / TEXTURE_SCALE - 0.5, (ys + 0.5) / TEXTURE_SCALE - 0.5


def stripes(period, angle_deg, phase=0.0):
    x, y = texel_grid()
    angle = np.deg2rad(angle_deg)
    u = x * np.cos(angle) + y * np.sin(angle)
    return np.sign(np.sin(2 * np.pi * (u / period + phase))).astype(np.float32)


def windows(period_x, period_y, fill=0.55):
    x, y = texel_grid()
    inside = ((np.mod(x, period_x) < fill * period_x) & (np.mod(y, period_y) < fill * period_y))
    return np.where(inside, -1.0, 1.0).astype(np.float32)


class Surface:
    """A plane d = a x + b y + c (left-image pixels) over a region of the left image, textured by
    a map over left-image coordinates (grey levels)."""

    def __init__(self, plane, texture, box=None, ellipse=False):
        self.a, self.b, self.c = plane
        self.texture = texture.astype(np.float32)
        self.box = box  # (x0, y0, x1, y1) in the left image, None = everywhere
        self.ellipse = ellipse

    def covers(self, x, y):
        if self.box is None:
            return np.ones(x.shape, bool)
        x0, y0, x1, y1 = self.box
        if not self.ellipse:
            return (x >= x0) & (x < x1) & (y >= y0) & (y < y1)
        cx, cy, rx, ry = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2, (y1 - y0) / 2
        return ((x - cx) / rx) ** 2 + ((y - cy) / ry) ** 2 < 1.0

    def left_x(self, x_view, y, right_view):
        # The right view sees left point x where x - d(x, y) = x_view (rectified: same row).
        return (x_view + self.b * y + self.c) / (1.0 - self.a) if right_view else x_view

    def shade(self, x, y):
        return cv2.remap(self.texture, (x + 0.5) * TEXTURE_SCALE - 0.5,
                         (y + 0.5) * TEXTURE_SCALE - 0.5, cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REFLECT)


def visible_surface(surfaces, x, y, right_view):
    """(index, left x, disparity) of the nearest surface seen at view pixels (x, y)."""
    best = np.full(x.shape, -1, np.int32)
    best_d = np.full(x.shape, -np.inf, np.float32)
    best_x = np.zeros(x.shape, np.float32)
    for index, surface in enumerate(surfaces):
        xl = surface.left_x(x, y, right_view)
        d = surface.a * xl + surface.b * y + surface.c
        take = surface.covers(xl, y) & (d > best_d)
        best[take], best_d[take], best_x[take] = index, d[take], xl[take]
    return best, best_x, best_d


def design_grid(scale, ox=0.0, oy=0.0):
    """Design coordinates (the 640 x 480 frame the scenes are drawn in) of the pixels of an image
    `scale` times its size, each moved by (ox, oy) of its own pixels."""
    rows, cols = int(round(HEIGHT * scale)), int(round(WIDTH * scale))
    y, x = np.mgrid[0:rows, 0:cols].astype(np.float32)
    return (x + ox + 0.5) / scale - 0.5, (y + oy + 0.5) / scale - 0.5


def render_view(surfaces, right_view, scale, samples=2):
    offsets = (np.arange(samples) + 0.5) / samples - 0.5
    total = None
    for oy in offsets:
        for ox in offsets:
            x, y = design_grid(scale, ox, oy)
            total = np.zeros(x.shape, np.float32) if total is None else total
            index, xl, _ = visible_surface(surfaces, x, y, right_view)
            for k, surface in enumerate(surfaces):
                seen = index == k
                if seen.any():
                    total[seen] += surface.shade(xl, y)[seen]
    return total / samples ** 2


def render_pair(surfaces, rng, right_gain=1.0, noise_sigma=2.0, scale=None):
    """Left and right images, the left ground truth (NaN unknown) and the non-occluded mask, at
    `scale` (default SCALE) times 640 x 480: a camera-sized image of the same scene, disparities
    scaled with it."""
    scale = SCALE if scale is None else scale
    left = render_view(surfaces, False, scale)
    right = render_view(surfaces, True, scale) * right_gain
    x, y = design_grid(scale)
    index, _, design_truth = visible_surface(surfaces, x, y, False)
    # The right view's pixel x - d (d in design units) must see the same surface.
    right_index, _, _ = visible_surface(surfaces, x - design_truth, y, True)
    truth = design_truth * scale
    columns = np.arange(x.shape[1])[None, :]
    xr = np.round(columns - truth).astype(int)
    visible = (xr >= 0) & (xr < x.shape[1]) & (right_index == index)
    truth = np.where(truth > 0, truth, np.nan)

    def camera(image):
        return np.clip(image + rng.normal(0.0, noise_sigma, image.shape), 0, 255).astype(np.uint8)

    return camera(left), camera(right), truth.astype(np.float64), visible


def markings(rng, texture, count, contrast):
    """Faint printed marks (lines and rings) on a texture map: the only edges of a plain surface."""
    for _ in range(count):
        value = float(rng.choice([-1, 1]) * rng.uniform(*contrast))
        centre = (int(rng.uniform(0, WIDTH)) * TEXTURE_SCALE, int(rng.uniform(0, HEIGHT)) * TEXTURE_SCALE)
        mark = np.zeros_like(texture)
        if rng.uniform() < 0.5:
            end = (centre[0] + int(rng.uniform(-200, 200)) * TEXTURE_SCALE,
                   centre[1] + int(rng.uniform(-120, 120)) * TEXTURE_SCALE)
            cv2.line(mark, centre, end, value, int(rng.uniform(2, 6)) * TEXTURE_SCALE)
        else:
            cv2.circle(mark, centre, int(rng.uniform(10, 50)) * TEXTURE_SCALE, value,
                       int(rng.uniform(2, 5)) * TEXTURE_SCALE)
        texture = texture + mark
    return texture


def lowtex_scene(rng):
    background = Surface((rng.uniform(-0.02, 0.02), rng.uniform(0.0, 0.03), rng.uniform(8, 14)),
                         markings(rng, 120 + 12 * smooth_noise(rng, 2, octaves=2), 12, (25, 50)))
    surfaces = [background]
    for _ in range(4):
        w, h = rng.uniform(90, 220), rng.uniform(70, 180)
        x0, y0 = rng.uniform(0, WIDTH - w), rng.uniform(0, HEIGHT - h)
        plane = (rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), rng.uniform(18, 50))
        shading = rng.uniform(50, 210) + 6 * smooth_noise(rng, 3, octaves=2)
        surfaces.append(Surface(plane, markings(rng, shading, 6, (25, 50)),
                                (x0, y0, x0 + w, y0 + h), rng.uniform() < 0.4))
    return render_pair(surfaces, rng, noise_sigma=1.5)


def repeated_scene(rng):
    background = Surface((0.0, rng.uniform(0.0, 0.02), rng.uniform(6, 12)),
                         125 + 40 * smooth_noise(rng, 24, octaves=4))
    surfaces = [background]
    for _ in range(4):
        w, h = rng.uniform(100, 240), rng.uniform(80, 200)
        x0, y0 = rng.uniform(0, WIDTH - w), rng.uniform(0, HEIGHT - h)
        plane = (rng.uniform(-0.04, 0.04), rng.uniform(-0.04, 0.04), rng.uniform(16, 48))
        period = rng.uniform(6, 16)
        pattern = stripes(period, rng.uniform(-20, 20), rng.uniform()) if rng.uniform() < 0.6 \
            else windows(period, rng.uniform(6, 16))
        texture = rng.uniform(80, 170) + rng.uniform(30, 70) * pattern \
            + 8 * smooth_noise(rng, 4, octaves=3)
        surfaces.append(Surface(plane, texture, (x0, y0, x0 + w, y0 + h)))
    return render_pair(surfaces, rng)


def outdoor_scene(rng):
    horizon = rng.uniform(150, 220)
    # Ground: disparity 0 at the horizon, growing down the image.
    ground_slope = rng.uniform(0.12, 0.2)
    ground = Surface((0.0, ground_slope, -ground_slope * horizon),
                     110 + 45 * smooth_noise(rng, 24, octaves=5), (0, horizon, WIDTH, HEIGHT))
    sky = Surface((0.0, 0.0, 0.5), 215 + 6 * smooth_noise(rng, 2, octaves=2))
    surfaces = [sky, ground]
    x = 0.0
    while x < WIDTH:
        w = rng.uniform(80, 200)
        top = rng.uniform(20, horizon - 40)
        d = rng.uniform(3, 12)
        facade = rng.uniform(90, 170) + 40 * windows(rng.uniform(8, 18), rng.uniform(12, 22)) \
            + 10 * smooth_noise(rng, 12, octaves=4)
        surfaces.append(Surface((0.0, 0.0, d), facade, (x, top, x + w, horizon + 2)))
        x += w + rng.uniform(-10, 40)
    for _ in range(3):  # trees and posts nearer the cameras, standing on the ground
        w, h = rng.uniform(30, 90), rng.uniform(80, 220)
        x0 = rng.uniform(0, WIDTH - w)
        foot = rng.uniform(horizon + 60, HEIGHT)
        d = ground_slope * (foot - horizon)
        texture = 90 + 60 * smooth_noise(rng, 40, octaves=4)
        surfaces.append(Surface((0.0, 0.0, d), texture, (x0, foot - h, x0 + w, foot),
                                rng.uniform() < 0.5))
    return render_pair(surfaces, rng, right_gain=rng.uniform(0.85, 1.15), noise_sigma=3.0)


SCENES = {"lowtex": lowtex_scene, "repeated": repeated_scene, "outdoor": outdoor_scene}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="../shared/datasets",
                        help="folder of real pairs with ground truth (default: %(default)s)")
    parser.add_argument("--out", required=True, help="new folder: OUT/tune and OUT/check")
    parser.add_argument("--check-names", default="Wood2,ArtL,Jadeplant,2014_Q_Teddy,eth3d",
                        help="comma-separated name parts of the real pairs that go to the check "
                             "part (default: %(default)s)")
    parser.add_argument("--variants", default="geometric,radiometric",
                        help="variants of each real pair, comma-separated, or none: "
                             + ", ".join(VARIANTS) + " (default: %(default)s)")
    parser.add_argument("--scenes", type=int, default=2,
                        help="rendered scenes of each kind in each part (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=42, help="seed of every draw (default: %(default)s)")
    parser.add_argument("--render-scale", type=float, default=1.0,
                        help="rendered scenes at this many times 640 x 480, the same scenes "
                             "(2.25: 1440 x 1080, 1.6 megapixels; default: %(default)s)")
    args = parser.parse_args()
    global SCALE
    SCALE = args.render_scale
    if not 0.25 <= SCALE <= 4.0:
        parser.error("--render-scale must lie in 0.25 .. 4")

    variants = [] if args.variants == "none" else args.variants.split(",")
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        parser.error(f"unknown variant {unknown[0]} (known: {', '.join(VARIANTS)})")
    if args.scenes < 0:
        parser.error("--scenes must be 0 or more")
    if not os.path.isdir(args.dataset):
        parser.error(f"--dataset {args.dataset} is not a folder")
    out = os.path.abspath(args.out)
    if os.path.commonpath([out, os.path.abspath(args.dataset)]) == os.path.abspath(args.dataset):
        parser.error("--out must not lie inside --dataset (outputs never overwrite inputs)")
    if os.path.exists(out) and (not os.path.isdir(out) or os.listdir(out)):
        parser.error(f"--out {args.out} exists and is not an empty folder")

    check_names = [name for name in args.check_names.split(",") if name]
    rng = np.random.default_rng(args.seed)
    written = {"tune": 0, "check": 0}
    for name in sorted(os.listdir(args.dataset)):
        directory = os.path.join(args.dataset, name)
        loaded = fit_confidence.load_pair(directory) if os.path.isdir(directory) else None
        if loaded is None:
            continue
        part = "check" if any(c in name for c in check_names) else "tune"
        left_path, right_path, truth = loaded
        left = cv2.imread(left_path, cv2.IMREAD_COLOR)
        right = cv2.imread(right_path, cv2.IMREAD_COLOR)
        visible = confident_errors.visible(directory, truth)
        os.makedirs(os.path.join(out, part), exist_ok=True)
        os.symlink(os.path.abspath(directory), os.path.join(out, part, name))
        written[part] += 1
        for variant in variants:
            made = VARIANTS[variant](left, right, truth, visible, rng)
            write_pair(os.path.join(out, part, f"{name}_{variant}"), *made)
            written[part] += 1
    for part in ("tune", "check"):
        for kind, scene in SCENES.items():
            for index in range(args.scenes):
                left, right, truth, visible = scene(rng)
                write_pair(os.path.join(out, part, f"rendered_{kind}_{part}{index}"),
                           left, right, truth, visible)
                written[part] += 1
    print(f"{out}: {written['tune']} tuning pairs, {written['check']} check pairs")


if __name__ == "__main__":
    main()
