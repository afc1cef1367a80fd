#!/usr/bin/env python3
"""The cylinder a breast's fill-in is laid over, about two axes, on one model folder.

Usage: fill_in_axis.py MODEL_DIR LANDMARKS_JSON

For each breast: the chest around the cut curve (the filled base's triangles outside
both fill-ins, within the loop's extent + 40 mm of its centroid), the axis its
area-weighted normals vary least along, and a Kasa circle fitted about (a) the
sternum's direction Px->Pj and (b) that axis. Prints the axis's angle from the
sternum (its top tilted forward and outwards), and per axis the radius, the RMS
radial residual of the band's vertices and the smallest distance of the cut curve from the axis
as a fraction of the radius (near 0: the axis passes through the fill-in, whose
cylinder coordinates are singular there). See docs/dev/fill-in-axis.md.
"""
import json
import sys

import numpy as np

BAND_MM = 40.0


def read_ply(path):
    """Vertices and triangles of a binary little-endian or ASCII PLY (x, y, z first)."""
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        body = f.read()
    ascii_format = any(l.startswith("format ascii") for l in header)
    counts, props, current = {}, {}, None
    for line in header:
        parts = line.split()
        if parts[0] == "element":
            current = parts[1]
            counts[current] = int(parts[2])
            props[current] = []
        elif parts[0] == "property":
            props[current].append(parts[1:])
    sizes = {"float": "f4", "float32": "f4", "double": "f8", "float64": "f8", "uchar": "u1",
             "uint8": "u1", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4"}
    nv, nf = counts["vertex"], counts["face"]
    if ascii_format:
        tokens = body.decode().split()
        k = len(props["vertex"])
        v = np.array(tokens[: nv * k], float).reshape(nv, k)[:, :3]
        rest = np.array(tokens[nv * k:], int).reshape(nf, 4)
        return v, rest[:, 1:]
    vdtype = np.dtype([(p[-1], "<" + sizes[p[0]]) for p in props["vertex"]])
    vertices = np.frombuffer(body, vdtype, nv)
    v = np.stack([vertices["x"], vertices["y"], vertices["z"]], 1).astype(float)
    count_type, index_type = props["face"][0][1], props["face"][0][2]
    fdtype = np.dtype([("n", "<" + sizes[count_type]), ("i", "<" + sizes[index_type], 3)])
    faces = np.frombuffer(body, fdtype, nf, offset=nv * vdtype.itemsize)
    return v, faces["i"].astype(int)


def circle_about(points, centre, axis, lateral, loop):
    first = np.cross(axis, lateral)
    first /= np.linalg.norm(first)
    second = np.cross(axis, first)
    q = np.stack([(points - centre) @ first, (points - centre) @ second], 1)
    d, e, f = np.linalg.lstsq(np.c_[q, np.ones(len(q))], -(q**2).sum(1), rcond=None)[0]
    across = np.array([-d / 2, -e / 2])
    radius = np.sqrt(max(across @ across - f, 0.0))
    on_axis = centre + across[0] * first + across[1] * second

    def radial(x):
        offset = x - on_axis
        return np.linalg.norm(offset - np.outer(offset @ axis, axis), axis=1)

    rms = np.sqrt(np.mean((radial(points) - radius) ** 2))
    return radius, rms, radial(loop).min() / radius


def main(model_dir, landmarks_path):
    marks = json.load(open(landmarks_path))["landmarks"]
    sternum = np.subtract(marks["Pj"], marks["Px"])
    sternum /= np.linalg.norm(sternum)
    lateral = np.subtract(marks["Pcl"], marks["Pcr"])
    lateral -= sternum * (lateral @ sternum)
    lateral /= np.linalg.norm(lateral)
    anterior = np.cross(lateral, sternum)
    base_v, base_f = read_ply(f"{model_dir}/filled_base.ply")
    # The base as the fill-ins see it: the filled base without either fill-in (triangles
    # with a corner inside a fill-in, not on its cut curve).
    loops = {side: np.array([[float(x) for x in l.split()[1:4]]
                             for l in open(f"{model_dir}/cut_curve_{side}.obj") if l.startswith("v ")])
             for side in ("left", "right")}
    in_fill = {tuple(p) for side in loops for p in read_ply(f"{model_dir}/fill_{side}.ply")[0].round(6)}
    on_loop = {tuple(p) for side in loops for p in loops[side].round(6)}
    interior = np.array([tuple(p) in in_fill and tuple(p) not in on_loop for p in base_v.round(6)])
    faces = base_f[~interior[base_f].any(1)]
    for side, outwards in (("left", 1.0), ("right", -1.0)):
        loop = loops[side]
        seg = np.linalg.norm(np.roll(loop, -1, 0) - loop, axis=1)
        weights = 0.5 * (seg + np.roll(seg, 1))
        centroid = (loop * weights[:, None]).sum(0) / weights.sum()
        reach = np.linalg.norm(loop - centroid, axis=1).max() + BAND_MM
        corners = base_v[faces]
        near = np.linalg.norm(corners.mean(1) - centroid, axis=1) <= reach
        normals = np.cross(corners[near, 1] - corners[near, 0], corners[near, 2] - corners[near, 0])
        unit = normals / np.linalg.norm(normals, axis=1)[:, None]
        eigenvalues, vectors = np.linalg.eigh(normals.T @ unit)
        axis = vectors[:, 0] * np.sign(vectors[:, 0] @ sternum)
        tilt = np.degrees(np.arctan2(axis @ anterior, axis @ sternum))
        roll = np.degrees(np.arcsin(outwards * (axis @ lateral)))
        band = base_v[np.unique(faces[near])]
        rows = [circle_about(band, centroid, a, lateral, loop) for a in (sternum, axis)]
        print(f"{side}: chest axis tilted {tilt:.0f}° forward, {roll:.0f}° outwards "
              f"(eigenvalues {eigenvalues[0] / eigenvalues[2]:.2f} / {eigenvalues[1] / eigenvalues[2]:.2f}); "
              + "; ".join(f"{name}: R {r:.0f} mm, RMS {rms:.1f} mm, loop at {m:.2f} R"
                          for name, (r, rms, m) in zip(("sternum", "chest axis"), rows)))


if __name__ == "__main__":
    main(*sys.argv[1:3])
