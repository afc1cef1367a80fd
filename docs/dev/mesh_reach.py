#!/usr/bin/env python3
"""How the skin differs between a simulation at the default resolution and one on a
finer mesh, over all the moved skin and over the skin the coarser mesh reaches.

Usage: mesh_reach.py SCAN_PLY FINE_SIM_DIR COARSE_SIM_DIR [NEAR_MM ...]

The two folders are `mammaplan simulate` outputs of the same scan (same vertex order),
on models built with different `--elements`. Over the scan vertices the finer result
moves more than 1 mm, prints the RMS / 95th percentile / largest distance between the
two simulated scans; then the same over the vertices within NEAR_MM (default 3 and 4.5)
of the coarser mesh's nearest vertex (its `fe_result.vtu` points), and where the
vertices that differ by more than 1.5 mm lie. Needs numpy and scipy. See
docs/dev/discretisation.md (session 38).
"""
import sys

import numpy as np
from scipy.spatial import cKDTree

from fill_in_axis import read_ply
from volume_balance import read_vtu


def summary(e):
    return f"RMS {np.sqrt((e ** 2).mean()):.2f} / p95 {np.percentile(e, 95):.2f} / max {e.max():.2f}"


def main():
    scan, fine_dir, coarse_dir = sys.argv[1:4]
    near = [float(x) for x in sys.argv[4:]] or [3.0, 4.5]
    rest = read_ply(scan)[0]
    fine = read_ply(f"{fine_dir}/simulated_scan.ply")[0]
    coarse = read_ply(f"{coarse_dir}/simulated_scan.ply")[0]
    moved = np.linalg.norm(fine - rest, axis=1) > 1.0
    diff = np.linalg.norm(coarse - fine, axis=1)
    print(f"moved {moved.sum()}: {summary(diff[moved])}")
    reach, _ = cKDTree(read_vtu(f"{coarse_dir}/fe_result.vtu")["points"]).query(rest)
    for mm in near:
        kept = moved & (reach < mm)
        print(f"within {mm} mm of the coarser mesh ({kept.sum()}): {summary(diff[kept])}")
    big = moved & (diff > 1.5)
    if big.any():
        d = np.percentile(reach[big], [0, 50, 100])
        print(f"over 1.5 mm: {big.sum()} vertices, {d[0]:.1f} / {d[1]:.1f} / {d[2]:.1f} mm "
              "(min / median / max) from the coarser mesh's nearest vertex")


if __name__ == "__main__":
    main()
