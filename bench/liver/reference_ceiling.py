#!/usr/bin/env python3
"""What a SLIVER07 score means on a scan's grid: the reference's own outline moved by one pixel.

For each labelled scan, the reference liver is eroded and dilated by one pixel in every axial
slice (4-neighbour structuring element) and scored against itself with `lseg eval`. A
segmentation that disagrees with the reference by a pixel all round scores about this; the
human second rater's 75 was measured on CTs of 0.5-0.8 mm pixels.

    /usr/bin/python3 bench/liver/reference_ceiling.py [--bin build/tools] [--data ../shared/data]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from scipy import ndimage


def read_mhd(path):
    header = {}
    for line in open(path):
        if "=" in line:
            k, v = line.split("=", 1)
            header[k.strip()] = v.strip()
    dims = [int(x) for x in header["DimSize"].split()]
    types = {"MET_UCHAR": np.uint8, "MET_SHORT": np.int16, "MET_USHORT": np.uint16, "MET_INT": np.int32}
    raw = os.path.join(os.path.dirname(path), header["ElementDataFile"])
    return header, np.fromfile(raw, dtype=types[header["ElementType"]]).reshape(dims[::-1])


def write_mhd(path, header, mask):
    raw = os.path.basename(path)[:-4] + ".raw"
    lines = []
    for k, v in header.items():
        if k == "ElementType":
            v = "MET_UCHAR"
        elif k == "ElementDataFile":
            continue
        lines.append(f"{k} = {v}")
    lines.append(f"ElementDataFile = {raw}")
    open(path, "w").write("\n".join(lines) + "\n")
    mask.astype(np.uint8).tofile(os.path.join(os.path.dirname(path), raw))


def main():
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default=os.path.join(repo, "build", "tools"))
    ap.add_argument("--data", default=os.path.join(repo, "..", "shared", "data"))
    a = ap.parse_args()
    scans = [("ct-small", "ct-small/liver.mhd", [1]), ("ct-dicom-jpeg2000", "ct-dicom-jpeg2000/liver.mhd", [1]),
             ("mr-small", "mr-small/labels.mhd", [5])]
    print("scan,pixel_mm,operation,dice,score")
    with tempfile.TemporaryDirectory() as work:
        for name, rel, labels in scans:
            path = os.path.join(a.data, rel)
            if not os.path.exists(path):
                print(f"reference_ceiling.py: {path} not found: {name} skipped", file=sys.stderr)
                continue
            header, lab = read_mhd(path)
            ref = np.isin(lab, labels)
            pixel = header["ElementSpacing"].split()[0]
            for op, f in (("erode", ndimage.binary_erosion), ("dilate", ndimage.binary_dilation)):
                moved = np.stack([f(s) for s in ref])
                out = os.path.join(work, f"{name}-{op}.mhd")
                write_mhd(out, header, moved)
                e = json.loads(subprocess.run([os.path.join(a.bin, "lseg"), "eval", out, path, "--ref-label",
                                               ",".join(map(str, labels)), "--json", "--quiet"],
                                              check=True, capture_output=True, text=True).stdout)
                print(f"{name},{float(pixel):.3f},{op} 1 px,{e['dice']:.4f},{e['score']['total']:.1f}")


if __name__ == "__main__":
    main()
