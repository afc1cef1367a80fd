#!/usr/bin/env python3
"""The table of issue 21's acceptance run (model_and_simulate_all.sh).

usage: model_and_simulate_table.py OUT_DIR

Per scan: breast volumes, reconstructed area share and volume (model.json), the closed
surface's volume, whether closed_surface.ply is watertight and outward (every directed
edge once and its reverse once, so each edge between exactly two consistently oriented
triangles, and a positive enclosed volume computed here from the file), the build time,
and `simulate`'s inverted element count and convergence. Needs numpy and plyfile.
"""

import json
import sys

import numpy as np
from plyfile import PlyData

NAMES = "v02_average pair1_pre pair1_post s01 s02 s03 s04 s05 s06 s07 s08 s09 s10 s11 s12"


def closed_and_outward(path):
    ply = PlyData.read(path)
    v = np.stack([ply["vertex"][c] for c in "xyz"], 1).astype(float)
    f = np.stack(ply["face"]["vertex_indices"])
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    _, once = np.unique(directed, axis=0, return_counts=True)
    reverse = {tuple(e) for e in directed[:, ::-1]}
    paired = all(tuple(e) in reverse for e in directed)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    volume_ml = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6000.0
    return (once == 1).all() and paired and volume_ml > 0.0, volume_ml


def main():
    out = sys.argv[1]
    print("| scan | breast L / R (ml) | reconstructed area share L / R | reconstructed ml L / R "
          "| closed surface (ml) | watertight, outward | build (ms) | R-MOD-100: inverted, converged |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in NAMES.split():
        model = json.load(open(f"{out}/{name}.json"))
        closed, volume_ml = closed_and_outward(f"{out}/m_{name}/closed_surface.ply")
        rec = model["reconstructed"]
        solver = json.load(open(f"{out}/{name}.sim.json"))["solver"]
        vol = model["breast_volume_ml"]
        print(f"| {name} | {vol['left']:.1f} / {vol['right']:.1f} "
              f"| {rec['left']['area_share']:.3f} / {rec['right']['area_share']:.3f} "
              f"| {rec['left']['volume_ml']:.1f} / {rec['right']['volume_ml']:.1f} "
              f"| {model['closed_surface_volume_ml']:.1f} "
              f"| {'yes' if closed else 'NO'} ({volume_ml:.1f} ml from the file) "
              f"| {model['timings']['total_ms']:.0f} "
              f"| {solver['inverted_elements']}, {solver['converged']} |")


if __name__ == "__main__":
    main()
