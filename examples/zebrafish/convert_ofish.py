"""Convert the zebrafish recording of lukaslang/ofish (GPL-3 data) into NPY files meshflow reads.

    python3 examples/zebrafish/convert_ofish.py PATH/TO/ofish/data/cxcr4aMO2_290112 OUT_DIR

Needs numpy, h5py and scipy (`pip install numpy h5py scipy`). Writes, in OUT_DIR:

- volumes/frame_K.npy for K = 114, 116, 120, 122, 140, 141, 142: (Z, Y, X) = (44, 512, 512)
  float32 confocal volumes (frames-A-B-unfiltered.mat: two frames each);
- cells/frame_001.npy … frame_151.npy: (N, 3) float64 cell centres in micrometres;
- voxel_size.txt: "1.6774,1.6774,7.1847" (x, y, z in micrometres), for --voxel-size.

Voxel (k, j, i) of a volume is at (1.6774 i, 1.6774 j, 7.1847 k) µm, meshflow's convention
(origin 0). The cell centres (thresholdedcenters.mat, MATLAB v5, 1-based voxel indices X, Y, Z
per frame) are put on the bright cells by i = Y - 1, j = X - 1, k = Z - 1: MATLAB's X and Y are
its column and row indices of the same (y, x) images. Frame 140 of the cells lies on the
volume of frame 140 with this map (mean volume value at the centres 0.94, against 0.87 for
the neighbouring frames' centres and 0.88 with k = Z).

Nothing here is meshflow code: the data stays outside the repository (GPL-3).
"""

import os
import sys

import h5py
import numpy as np
import scipy.io

VOXEL = np.array([1.6774, 1.6774, 7.1847])  # x, y, z in micrometres
PAIRS = ((114, 116), (120, 122), (140, 141), (140, 142))  # the volumes of the folder


def read_volume_pair(path):
    """The two volumes of a frames-A-B-unfiltered.mat file, as (z, y, x) float32.

    Files of 2014 and later are MATLAB v7.3 (HDF5), which h5py reads as (z, y, x); the one of
    2013 (frames 114-116) is MATLAB v5, which scipy reads in MATLAB's own (row, column, slice)
    order, i.e. (x, y, z) here: transposed to match."""
    if h5py.is_hdf5(path):
        with h5py.File(path, "r") as f:
            return [np.asarray(f[ref]["u"][()], dtype=np.float32) for ref in f["U"][:, 0]]
    pair = scipy.io.loadmat(path)["U"].ravel()
    return [np.asarray(c["u"][0, 0], dtype=np.float32).transpose(2, 1, 0) for c in pair]


def cell_centres(path):
    """(N, 3) micrometre positions of the cells of each of the 151 frames."""
    frames = scipy.io.loadmat(path)["F"]
    out = []
    for k in range(frames.shape[0]):
        s = frames[k, 0][0, 0]
        X, Y, Z = (np.asarray(s[c], dtype=np.float64).ravel() for c in ("X", "Y", "Z"))
        index = np.stack([Y - 1, X - 1, Z - 1], axis=1)  # (i, j, k)
        out.append(index * VOXEL)
    return out


def main(data, out):
    os.makedirs(os.path.join(out, "volumes"), exist_ok=True)
    os.makedirs(os.path.join(out, "cells"), exist_ok=True)
    written = {}
    for first, last in PAIRS:
        name = f"frames-{first}-{last}-unfiltered.mat"
        for frame, volume in zip((first, last), read_volume_pair(os.path.join(data, name))):
            if frame in written:
                assert np.array_equal(written[frame], volume), f"frame {frame} differs"
                continue
            written[frame] = volume
            np.save(os.path.join(out, "volumes", f"frame_{frame}.npy"), volume)
    for k, cells in enumerate(cell_centres(os.path.join(data, "thresholdedcenters.mat"))):
        np.save(os.path.join(out, "cells", f"frame_{k + 1:03d}.npy"), cells)
    with open(os.path.join(out, "voxel_size.txt"), "w") as f:
        f.write(",".join(f"{v:g}" for v in VOXEL) + "\n")
    frames = ", ".join(str(k) for k in sorted(written))
    print(f"wrote {out}: volumes of frames {frames} (44 x 512 x 512), cells of 151 frames")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
