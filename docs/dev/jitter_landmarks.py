#!/usr/bin/env python3
"""Writes a landmark file with every landmark moved by a random vector of at most
RADIUS mm (uniform in a ball), seeded: the landmarks another hand might have placed.

usage: jitter_landmarks.py IN.json OUT.json SEED [RADIUS_MM=4]
"""
import json
import random
import sys


def main():
    source, target, seed = sys.argv[1], sys.argv[2], int(sys.argv[3])
    radius_mm = float(sys.argv[4]) if len(sys.argv) > 4 else 4.0
    landmarks = json.load(open(source))
    draw = random.Random(seed)
    for name, point in landmarks["landmarks"].items():
        while True:
            step = [draw.uniform(-1.0, 1.0) for _ in range(3)]
            if sum(c * c for c in step) <= 1.0:
                break
        landmarks["landmarks"][name] = [p + radius_mm * s for p, s in zip(point, step)]
    json.dump(landmarks, open(target, "w"), indent=1)


if __name__ == "__main__":
    main()
