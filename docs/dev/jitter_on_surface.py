#!/usr/bin/env python3
"""Writes a landmark file with every landmark moved along the scan's surface by a random
step of at most RADIUS mm (uniform in the tangent disc), seeded, and put back on the
surface (the nearest scan vertex): the landmarks another hand might have clicked. Unlike jitter_landmarks.py, whose
steps leave the surface (a 6 mm draw lands more than 5 mm off it for a quarter of the
bodies, and `model` refuses that by design), every landmark stays on the skin.

The tangent plane at a landmark is the plane fitted (principal components) to the scan's
vertices within 8 mm of it; needs numpy and a binary little-endian PLY with float x, y,
z first among the vertex properties (the shared scans).

usage: jitter_on_surface.py SCAN.ply IN.json OUT.json SEED [RADIUS_MM=6]
"""
import json
import sys

import numpy as np

PATCH_MM = 8.0


def read_vertices(path):
    with open(path, "rb") as f:
        header = b""
        while not header.endswith(b"end_header\n"):
            header += f.readline()
        lines = header.decode("ascii").splitlines()
        assert "format binary_little_endian 1.0" in lines, "binary little-endian PLY only"
        count, properties, in_vertex = 0, [], False
        for line in lines:
            words = line.split()
            if words[:2] == ["element", "vertex"]:
                count, in_vertex = int(words[2]), True
            elif words[:1] == ["element"]:
                in_vertex = False
            elif words[:1] == ["property"] and in_vertex:
                properties.append(words[1])
        assert properties[:3] == ["float"] * 3 and all(p == "float" for p in properties)
        data = np.frombuffer(f.read(4 * len(properties) * count), dtype="<f4")
        return data.reshape(count, len(properties))[:, :3].astype(float)


def local_plane(vertices, point):
    """Centre and unit normal of the plane fitted to the vertices near `point`."""
    near = vertices[np.linalg.norm(vertices - point, axis=1) < PATCH_MM]
    if len(near) < 3:
        raise SystemExit(f"no scan surface within {PATCH_MM} mm of {point}")
    centre = near.mean(axis=0)
    _, _, axes = np.linalg.svd(near - centre)
    return centre, axes[2]


def main():
    scan, source, target, seed = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    radius_mm = float(sys.argv[5]) if len(sys.argv) > 5 else 6.0
    vertices = read_vertices(scan)
    landmarks = json.load(open(source))
    draw = np.random.default_rng(seed)
    for name, point in landmarks["landmarks"].items():
        point = np.array(point, dtype=float)
        centre, normal = local_plane(vertices, point)
        tangent = np.cross(normal, [1.0, 0.0, 0.0])
        if np.linalg.norm(tangent) < 0.5:
            tangent = np.cross(normal, [0.0, 1.0, 0.0])
        tangent /= np.linalg.norm(tangent)
        bitangent = np.cross(normal, tangent)
        # Uniform in the disc: radius by the square root of a uniform draw.
        angle, fraction = draw.uniform(0.0, 2.0 * np.pi), np.sqrt(draw.uniform())
        moved = point + radius_mm * fraction * (
            np.cos(angle) * tangent + np.sin(angle) * bitangent
        )
        # Back on the skin: the scan vertex nearest the step's end (a plane fitted there
        # can lie millimetres off the skin in the crease of a fold).
        nearest = vertices[np.argmin(np.linalg.norm(vertices - moved, axis=1))]
        landmarks["landmarks"][name] = nearest.tolist()
    json.dump(landmarks, open(target, "w"), indent=1)


if __name__ == "__main__":
    main()
