"""Forward change of the skin 30 mm above, at and 30 mm below each nipple.

Usage: python3 docs/dev/upper_pole.py PRE_SCAN.ply PRE_LANDMARKS.json SIM_DIR...

For each simulation folder, prints six numbers (mm): left nipple +30 / 0 / -30, then
right. The shared scans stand upright in their files (y up, z forward), so the file
frame is used as the standing frame; the skin's forward coordinate at a height is the
front-most scan vertex within 3 mm of that point in x and y.
"""
import json
import sys

import numpy as np
from plyfile import PlyData


def load(path):
    v = PlyData.read(path)["vertex"]
    return np.c_[v["x"], v["y"], v["z"]]


def front_z(points, x, y, radius=3.0):
    near = np.hypot(points[:, 0] - x, points[:, 1] - y) < radius
    return points[near, 2].max() if near.any() else float("nan")


def main():
    pre, landmarks = sys.argv[1], sys.argv[2]
    marks = json.load(open(landmarks))["landmarks"]
    before = load(pre)
    for sim in sys.argv[3:]:
        after = load(sim + "/simulated_scan.ply")
        row = []
        for nipple in ("Pnl", "Pnr"):
            x, y = marks[nipple][0], marks[nipple][1]
            for dy in (30, 0, -30):
                row.append(front_z(after, x, y + dy) - front_z(before, x, y + dy))
        print(sim, " ".join("%+.1f" % v for v in row))


if __name__ == "__main__":
    main()
