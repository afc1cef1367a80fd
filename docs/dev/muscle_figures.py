"""The pectoralis major's figures from model folders, as a Markdown table.

Usage: python3 docs/dev/muscle_figures.py MODEL_DIR...
(each written by `mammaplan model`; reads `pectoralis_major` and the finest spacing
from its model.json)
"""
import json
import os
import sys


def main():
    print("| body | medial border from midline (mm) L / R | lowest over sternum above Px (mm) "
          "| mean thickness (mm) | area (cm²) | volume (ml) | spacing (mm) |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for folder in sys.argv[1:]:
        report = json.load(open(os.path.join(folder, "model.json")))
        muscle = report["pectoralis_major"]
        spacing = report["levels"][0]["spacing_mm"]

        def pair(key, digits):
            cells = []
            for side in ("left", "right"):
                value = muscle[side][key] if muscle[side] else None
                cells.append("none" if value is None else f"{value:+.{digits}f}"
                             if key.startswith("lower") else f"{value:.{digits}f}")
            return " / ".join(cells)

        print(f"| {os.path.basename(folder.rstrip('/'))} | {pair('medial_border_from_midline_mm', 1)} "
              f"| {pair('lower_sternal_origin_above_px_mm', 1)} | {pair('mean_thickness_mm', 1)} "
              f"| {pair('area_cm2', 0)} | {pair('volume_ml', 0)} | {spacing:.1f} |")


if __name__ == "__main__":
    main()
