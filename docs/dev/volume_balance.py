#!/usr/bin/env python3
"""Volume balance of a simulation: the summed signed volume change of the implant
elements and of the tissue elements of `fe_result.vtu` between rest and result, and the
tissue's volume change by volume ratio J.

    python3 docs/dev/volume_balance.py SIM_DIR/fe_result.vtu

Reads the `displacement`, `connectivity` and `implant` arrays (zlib-compressed appended
data, as `simulate` writes them). Needs numpy.
"""
import re
import struct
import sys
import zlib

import numpy as np


def read_vtu(path):
    raw = open(path, "rb").read()
    start = raw.index(b"<AppendedData")
    data = raw[raw.index(b"_", start) + 1:]
    header = raw[:start].decode()
    arrays = {}
    pattern = (r'<DataArray type="(\w+)"(?: Name="(\w+)")? NumberOfComponents="(\d+)" '
               r'format="appended" offset="(\d+)"')
    for m in re.finditer(pattern, header):
        kind, name, components, offset = m.group(1), m.group(2) or "points", int(m.group(3)), int(m.group(4))
        blocks = struct.unpack("<Q", data[offset:offset + 8])[0]
        sizes = struct.unpack(f"<{blocks}Q", data[offset + 24:offset + 24 + 8 * blocks])
        at, buffer = offset + 24 + 8 * blocks, b""
        for size in sizes:
            buffer += zlib.decompress(data[at:at + size])
            at += size
        dtype = {"Float64": "<f8", "Int64": "<i8", "UInt8": "u1", "Float32": "<f4", "Int32": "<i4"}[kind]
        values = np.frombuffer(buffer, dtype)
        arrays[name] = values.reshape(-1, components) if components > 1 else values
    return arrays


def main():
    v = read_vtu(sys.argv[1])
    rest, moved = v["points"], v["points"] + v["displacement"]
    tets = v["connectivity"].reshape(-1, 4)
    implant = v["implant"] > 0.5

    def volumes(p):
        a, b, c, d = (p[tets[:, k]] for k in range(4))
        return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0

    v0 = volumes(rest)
    dv = volumes(moved) - v0
    ratio = dv / v0
    tissue = ~implant
    print(f"implant elements {dv[implant].sum() / 1000:.1f} ml, tissue {dv[tissue].sum() / 1000:.1f} ml "
          f"(lost {dv[tissue & (dv < 0)].sum() / 1000:.1f}, gained {dv[tissue & (dv > 0)].sum() / 1000:.1f})")
    for lo, hi in [(-1, -0.3), (-0.3, -0.1), (-0.1, -0.03), (-0.03, 0), (0, 0.03), (0.03, 0.1), (0.1, np.inf)]:
        m = tissue & (ratio >= lo) & (ratio < hi)
        print(f"  J - 1 in [{lo}, {hi}): {m.sum()} tissue elements, {dv[m].sum() / 1000:.1f} ml")


if __name__ == "__main__":
    main()
