#!/usr/bin/env python3
"""Where a simulation's inverted elements are.

usage: inverted_where.py SIM_DIR

Reads SIM_DIR/fe_result.vtu and prints, per element whose signed volume changed sign:
its centre (file frame, mm), its rest and final volume (mm^3), which corners carry the
`constrained` flag, its corners' displacement lengths and the range of displacement
lengths over the elements sharing a corner with it. Needs numpy and meshio.
"""

import sys

import meshio
import numpy as np


def signed_volumes(points, tets):
    a, b, c, d = (points[tets[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0


def main():
    mesh = meshio.read(f"{sys.argv[1]}/fe_result.vtu")
    tets = mesh.cells[0].data
    rest = mesh.points
    displacement = mesh.point_data["displacement"]
    constrained = mesh.point_data["constrained"].ravel().astype(int)
    before = signed_volumes(rest, tets)
    after = signed_volumes(rest + displacement, tets)
    for t in np.where(np.sign(after) != np.sign(before))[0]:
        corners = tets[t]
        around = np.unique(tets[np.any(np.isin(tets, corners), axis=1)].ravel())
        lengths = np.linalg.norm(displacement[around], axis=1)
        print(
            f"element {t}: centre {rest[corners].mean(axis=0).round(1)}, "
            f"volume {before[t]:.2f} -> {after[t]:.2f} mm^3, "
            f"constrained {constrained[corners]}, "
            f"|u| {np.linalg.norm(displacement[corners], axis=1).round(1)} mm, "
            f"around {lengths.min():.1f}-{lengths.max():.1f} mm"
        )


if __name__ == "__main__":
    main()
