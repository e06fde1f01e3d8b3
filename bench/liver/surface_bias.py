#!/usr/bin/env python3
"""Where a liver mask's outline lies against its reference: the signed distance [mm] from each
outer boundary voxel of the mask (in-plane, 4-neighbour, after filling each slice's holes) to the
reference's surface, + outside the reference, - inside. Its median is the systematic offset of
the outline (a leak moves the upper quantiles, not the median); the per-slice line shows where.

    /usr/bin/python3 bench/liver/surface_bias.py MASK.mhd REF.mhd 1,2,3,4 [--slices]

MetaImage inputs (`lseg liver --mask`); needs numpy and scipy (install-deps.sh --bench).
"""
import os
import sys

import numpy as np
from scipy import ndimage as ndi


def read_mhd(path):
    header = dict(line.split(" = ", 1) for line in open(path).read().strip().split("\n"))
    dims = [int(x) for x in header["DimSize"].split()]
    types = {"MET_UCHAR": np.uint8, "MET_SHORT": np.int16, "MET_USHORT": np.uint16, "MET_FLOAT": np.float32}
    data = np.fromfile(os.path.join(os.path.dirname(path), header["ElementDataFile"]),
                       dtype=types[header["ElementType"]]).reshape(dims[::-1])
    return data, [float(x) for x in header["ElementSpacing"].split()][::-1]


def main():
    mask, spacing = read_mhd(sys.argv[1])
    labels, _ = read_mhd(sys.argv[2])
    ref = np.isin(labels, [int(x) for x in sys.argv[3].split(",")])
    seg = np.array([ndi.binary_fill_holes(s) for s in mask > 0])
    # Signed distance to the reference's surface, taken half a voxel outside its boundary voxels.
    half = 0.5 * min(spacing)
    signed = np.where(ref, half - ndi.distance_transform_edt(ref, sampling=spacing),
                      ndi.distance_transform_edt(~ref, sampling=spacing) - half)
    boundary = seg & ~np.array([ndi.binary_erosion(s) for s in seg])
    d = signed[boundary]
    print("%d boundary voxels: median %+.2f mm, quartiles %+.2f / %+.2f mm, %.0f %% inside the reference"
          % (d.size, np.median(d), np.percentile(d, 25), np.percentile(d, 75), 100.0 * np.mean(d < 0)))
    if "--slices" in sys.argv:
        for k in range(seg.shape[0]):
            dk = signed[k][boundary[k]]
            if dk.size:
                print("slice %3d: %5d voxels, median %+.2f mm" % (k, dk.size, np.median(dk)))


if __name__ == "__main__":
    main()
