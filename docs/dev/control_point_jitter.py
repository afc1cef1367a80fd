#!/usr/bin/env python3
"""How much a breast's volume moves when its default control points move a little.

usage: control_point_jitter.py MAMMAPLAN OUT_DIR [RADIUS_MM] [DRAWS]

For each shared scan with its own landmarks (v02_average, pair1_pre, zoo s01-s12):
builds the default model, then DRAWS models (default 5) from its control_points.json
with every point of both breasts moved RADIUS_MM (default 3) in a random direction in
the file's horizontal plane (draw k uses seed k; the model snaps each point back to the
skin). Prints per body the default volumes and the range and standard deviation of
each side's volume over the draws. Needs numpy.
"""

import json
import os
import subprocess
import sys

import numpy as np

SCANS = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "scans")


def model(binary, scan_dir, name, out, extra):
    command = [
        binary, "model",
        "--scan", os.path.join(scan_dir, f"{name}.ply"),
        "--landmarks", os.path.join(scan_dir, f"{name}_landmarks.json"),
        "--out", out, "--json", *extra,
    ]
    run = subprocess.run(command, capture_output=True, text=True)
    if run.returncode != 0:
        print(f"{name}: {run.stderr.strip()[-300:]}", file=sys.stderr)
        return None
    volume = json.loads(run.stdout)["breast_volume_ml"]
    return volume["left"], volume["right"]


def main():
    binary, out = sys.argv[1], sys.argv[2]
    radius_mm = float(sys.argv[3]) if len(sys.argv) > 3 else 3.0
    draws = int(sys.argv[4]) if len(sys.argv) > 4 else 5
    bodies = [("v02_average", SCANS), ("pair1_pre", SCANS)]
    bodies += [(f"s{i:02d}", os.path.join(SCANS, "zoo")) for i in range(1, 13)]
    os.makedirs(out, exist_ok=True)
    for name, scan_dir in bodies:
        default_dir = os.path.join(out, name)
        base = model(binary, scan_dir, name, default_dir, [])
        if base is None:
            continue
        with open(os.path.join(default_dir, "control_points.json")) as f:
            points = json.load(f)
        volumes = []
        for seed in range(1, draws + 1):
            rng = np.random.default_rng(seed)
            moved = dict(points)
            for side in ("left", "right"):
                p = np.array(points[side])
                step = rng.normal(size=(len(p), 2))
                step *= radius_mm / np.linalg.norm(step, axis=1, keepdims=True)
                moved[side] = (p + np.c_[step[:, 0], step[:, 1], np.zeros(len(p))]).tolist()
            path = os.path.join(out, f"{name}_draw{seed}.json")
            with open(path, "w") as f:
                json.dump(moved, f)
            v = model(binary, scan_dir, name, os.path.join(out, "draw"), ["--control-points", path])
            volumes.append(v if v is not None else (np.nan, np.nan))
        v = np.array(volumes)
        spread = np.nanmax(v, axis=0) - np.nanmin(v, axis=0)
        print(
            f"{name}: {base[0]:.1f} / {base[1]:.1f} ml; range {spread[0]:.1f} / {spread[1]:.1f}; "
            f"std {np.nanstd(v[:, 0]):.1f} / {np.nanstd(v[:, 1]):.1f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
