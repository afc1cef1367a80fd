"""Where the fold lies before and after simulations with the fold lowered by 0 and 10 mm
(docs/dev/standing-frame.md, "Does the simulated skin show the new fold?"). Run in a
folder holding ph.ply and ph.json (`mammaplan phantom`) and the simulation folders
sim0/ and sim10/. Needs numpy and plyfile.

Two measures on the front profile z(y) of the skin in 4 mm wide vertical strips at
PSMF's x and 10 mm either side, relative to PSMF's height:
- crease: the largest second difference of z(y) (the sharpest turn);
- fold: the lowest height where the skin stands more than 2 mm in front of the chest
  line (a straight line fitted to the pre-operative profile 12-40 mm below PSMF), the
  junction of breast and chest wall."""
import json
import numpy as np
from plyfile import PlyData


def load(path):
    d = PlyData.read(path)['vertex']
    return np.c_[d['x'], d['y'], d['z']]


landmarks = json.load(open('ph.json'))['landmarks']
heights = np.arange(-45, 25, 0.5)


def profile(points, fold, x0):
    near = (np.abs(points[:, 0] - x0) < 2) & (points[:, 2] > fold[2] - 60)
    strip = points[near]
    z = []
    for y in heights:
        row = np.abs(strip[:, 1] - (fold[1] + y)) < 0.75
        z.append(strip[row, 2].max() - fold[2] if row.any() else np.nan)
    return np.array(z)


def crease(z):
    smooth = np.convolve(np.nan_to_num(z), np.ones(7) / 7, 'same')
    second = smooth[4:] - 2 * smooth[2:-2] + smooth[:-4]
    inside = (heights[2:-2] > -40) & (heights[2:-2] < 20)
    return heights[2:-2][np.argmax(np.where(inside, second, -np.inf))]


pre = load('ph.ply')
sims = {name: load(name + '/simulated_scan.ply') for name in ('sim0', 'sim10')}
for side in ('l', 'r'):
    fold = np.array(landmarks['PSMF' + side])
    for dx in (-10, 0, 10):
        x0 = fold[0] + dx
        z_pre = profile(pre, fold, x0)
        fit = (heights >= -40) & (heights <= -12) & ~np.isnan(z_pre)
        slope, offset = np.polyfit(heights[fit], z_pre[fit], 1)

        def junction(z):
            in_front = (z - (offset + slope * heights)) > 2.0
            return heights[np.argmax(in_front & (heights > -40))]

        row = [(name, profile(points, fold, x0)) for name, points in sims.items()]
        print(f"{side} {dx:+d} mm: fold pre {junction(z_pre):+.1f} " +
              " ".join(f"{name} {junction(z):+.1f}" for name, z in row) +
              f" | crease pre {crease(z_pre):+.1f} " +
              " ".join(f"{name} {crease(z):+.1f}" for name, z in row))
