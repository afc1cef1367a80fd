"""How close each breast's cut curve comes to the midline between Pj and Px.

The session holds the tissue within 10 mm of the midline (the sternal frame's x = 0
plane through Pj) from Pj down to Px (`STERNUM_HALF_WIDTH_MM`); breast tissue lies
inside the cut curves, so a cut curve further than 10 mm from the midline over that
height means the strip holds none of it. Prints a Markdown row per body.

    python3 ../shared/tools/envelope.py --implant catalog:R-MOD-115 --keep DIR
    python3 docs/dev/strip_gap.py DIR
"""
import glob
import json
import os
import sys

import numpy as np


def curve(path):
    return np.array(
        [[float(t) for t in line.split()[1:4]] for line in open(path) if line.startswith("v ")]
    )


def main(keep_dir):
    print("| body | left cut curve to the midline (mm) | right |")
    print("| --- | --- | --- |")
    for folder in sorted(glob.glob(os.path.join(keep_dir, "*-model"))):
        model = json.load(open(os.path.join(folder, "model.json")))
        marks = json.load(open(model["landmarks"]))["landmarks"]
        pj, px = np.array(marks["Pj"]), np.array(marks["Px"])
        up = (pj - px) / np.linalg.norm(pj - px)
        x = np.array(marks["Pcl"]) - np.array(marks["Pcr"])
        x -= up * np.dot(x, up)
        x /= np.linalg.norm(x)
        height = np.dot(pj - px, up)
        gaps = []
        for side in ("left", "right"):
            points = curve(os.path.join(folder, f"cut_curve_{side}.obj"))
            h = (points - px) @ up
            beside = (h >= 0) & (h <= height)
            gaps.append(np.abs((points[beside] - pj) @ x).min() if beside.any() else float("nan"))
        name = os.path.basename(folder)[: -len("-model")]
        print(f"| {name} | {gaps[0]:.1f} | {gaps[1]:.1f} |")


if __name__ == "__main__":
    main(sys.argv[1])
