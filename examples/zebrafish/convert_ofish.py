"""Convert the zebrafish recording of lukaslang/ofish (GPL-3 data) into NPY files meshflow reads.

    python3 examples/zebrafish/convert_ofish.py PATH/TO/ofish/data/cxcr4aMO2_290112 OUT

Needs numpy, h5py and scipy (`pip install numpy h5py scipy`). The folder holds four pairs of
volumes, frames-A-B-unfiltered.mat for A-B = 114-116, 120-122, 140-141, 140-142, and the cell
centres, thresholdedcenters.mat. Any of them may be missing: what is there is converted, and
the missing ones are named. Writes, in OUT:

- volumes/frame_K.npy for the frames K of the pairs found (all: 114, 116, 120, 122, 140, 141,
  142): (Z, Y, X) = (44, 512, 512) float32 confocal volumes;
- voxel_size.txt: "1.6774,1.6774,7.1847" (x, y, z in micrometres), for --voxel-size;
- cells/frame_001.npy … frame_151.npy: (N, 3) float64 cell centres in micrometres;
- A-B/volumes/frame_A.npy, frame_B.npy (hard links to volumes/, copies where linking fails)
  and A-B/cells/frame_A.npy, frame_B.npy for each pair found: one folder per pair for the CLI
  (its cells need thresholdedcenters.mat; without it only A-B/volumes is written).

Then, for one pair (here 140 → 141; likewise 114-116, 120-122, 140-142):

    meshflow surface OUT/140-141/cells --out surf --vertices 65000
    meshflow sample OUT/140-141/volumes surf --voxel-size 1.6774,1.6774,7.1847
    meshflow match OUT/140-141/cells --out tracks.npy
    meshflow solve surf --out flow --regularizer strain --time-scale 0 \\
        --ground-truth-tracks tracks.npy --png

and `cargo run --release --example zebrafish -- OUT` runs every pair converted.
Everything is read and checked before anything is written; each file is written under a
temporary name and renamed, so a failed run leaves no half-written file. Re-running into the
same OUT replaces its files.

Voxel (k, j, i) of a volume is at (1.6774 i, 1.6774 j, 7.1847 k) µm, meshflow's convention
(origin 0). The cell centres (thresholdedcenters.mat, MATLAB v5, 1-based voxel indices X, Y, Z
per frame) are put on the bright cells by i = Y - 1, j = X - 1, k = Z - 1: MATLAB's X and Y are
its column and row indices of the same (y, x) images. Frame 140 of the cells lies on the
volume of frame 140 with this map (mean volume value at the centres 0.94, against 0.87 for
the neighbouring frames' centres and 0.88 with k = Z).

Nothing here is meshflow code: the data stays outside the repository (GPL-3).
"""

import os
import shutil
import sys

PROG = "convert_ofish.py"
USAGE = f"usage: python3 {PROG} PATH/TO/ofish/data/cxcr4aMO2_290112 OUT  (--help: the layout)"

try:
    import h5py
    import numpy as np
    import scipy.io
except ImportError as e:
    # Before anything else: a traceback for a missing module says nothing about the fix.
    why = " ".join(str(e).split())
    sys.exit(f"{PROG}: needs numpy, h5py and scipy ({why}): pip install numpy h5py scipy")

VOXEL = np.array([1.6774, 1.6774, 7.1847])  # x, y, z in micrometres
PAIRS = ((114, 116), (120, 122), (140, 141), (140, 142))  # the volumes of the folder
CENTRES = "thresholdedcenters.mat"


class Failure(Exception):
    """A one-line reason to stop, printed without a traceback."""


def pair_file(first, last):
    return f"frames-{first}-{last}-unfiltered.mat"


def reason(e):
    """An exception's message on one line (h5py's and scipy's may span several)."""
    return " ".join(str(e).split()) or type(e).__name__


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


def read_checked(reader, path):
    """reader(path), any failure of a damaged or foreign file turned into one line naming it."""
    try:
        return reader(path)
    except KeyError as e:
        # scipy's KeyError is the bare name of the variable missing; h5py's a sentence.
        what = str(e.args[0]) if e.args else ""
        why = f"no variable {what!r} (not an ofish file?)" if what.isidentifier() else what or reason(e)
        raise Failure(f"cannot read {path}: {why}") from None
    except Exception as e:  # scipy, h5py and numpy raise many kinds on a damaged file
        raise Failure(f"cannot read {path}: {foreign(path) or reason(e)}") from None


def foreign(path):
    """Why path is no MATLAB file, if its start says so (scipy calls any such file truncated).

    v7.3 files are HDF5; v5 ones open with a text header "MATLAB 5.0 MAT-file"."""
    try:
        with open(path, "rb") as f:
            head = f.read(128)
        if not head:
            return "empty file"
        if not head.startswith(b"MATLAB") and not h5py.is_hdf5(path):
            return "not a MATLAB file"
    except OSError:
        pass  # unreadable: the reader's own message says why
    return None


def read_pairs(data, pairs):
    """{frame: volume} of the pairs, checking that a frame in two files is the same in both."""
    volumes, source = {}, {}
    for first, last in pairs:
        path = os.path.join(data, pair_file(first, last))
        pair = read_checked(read_volume_pair, path)
        if len(pair) != 2 or any(v.ndim != 3 for v in pair):
            shapes = ", ".join(str(v.shape) for v in pair)
            raise Failure(f"cannot read {path}: expected two 3-D volumes, found {shapes or 'none'}")
        for frame, volume in zip((first, last), pair):
            if frame in volumes:
                # Frame 140 is in two files: they must agree, or one OUT/volumes file would
                # silently stand for two different recordings.
                if not np.array_equal(volumes[frame], volume):
                    raise Failure(f"frame {frame} differs between {source[frame]} and {pair_file(first, last)}")
                continue
            volumes[frame], source[frame] = volume, pair_file(first, last)
    return volumes


class Writer:
    """Writes under OUT: folders only when a file goes in, each file complete or not at all."""

    def __init__(self, out):
        self.out = out
        self.created = []  # folders this run made, removed again if they stay empty

    def folder(self, *parts):
        path = os.path.join(self.out, *parts)
        missing = []
        head = path
        while head and not os.path.isdir(head):
            missing.append(head)
            head = os.path.dirname(head)
        os.makedirs(path, exist_ok=True)
        self.created.extend(reversed(missing))
        return path

    def _replace(self, path, make):
        """make(temporary path) in the folder of path, then rename it over path."""
        tmp = os.path.join(os.path.dirname(path), f".{os.path.basename(path)}.{os.getpid()}.tmp")
        try:
            make(tmp)
            os.replace(tmp, path)
        finally:
            # rename() leaves both names when they are already links to one file.
            if os.path.lexists(tmp):
                os.remove(tmp)

    def save(self, folder, name, array):
        def make(tmp):
            with open(tmp, "wb") as f:  # a file object: np.save would append .npy to a name
                np.save(f, array)

        self._replace(os.path.join(folder, name), make)

    def text(self, folder, name, text):
        def make(tmp):
            with open(tmp, "w") as f:
                f.write(text)

        self._replace(os.path.join(folder, name), make)

    def link(self, source, folder, name):
        """A hard link to source (no second copy of 46 MB), or a copy where links fail."""

        def make(tmp):
            try:
                os.link(source, tmp)
            except OSError:  # another file system, FAT, a share without links
                shutil.copyfile(source, tmp)

        self._replace(os.path.join(folder, name), make)

    def drop_empty_folders(self):
        for path in reversed(self.created):
            try:
                os.rmdir(path)  # only succeeds on an empty folder
            except OSError:
                pass


def write_all(w, volumes, pairs, cells):
    """Writes everything read; returns the lines to print."""
    lines = []
    out = w.out
    if volumes:
        folder = w.folder("volumes")
        for frame, volume in sorted(volumes.items()):
            w.save(folder, f"frame_{frame}.npy", volume)
        w.text(w.folder(), "voxel_size.txt", ",".join(f"{v:g}" for v in VOXEL) + "\n")
        shape = " x ".join(str(n) for n in next(iter(volumes.values())).shape)
        frames = ", ".join(str(k) for k in sorted(volumes))
        lines.append(f"wrote {folder}: frame_K.npy for K = {frames} ({shape} float32), and voxel_size.txt")
    if cells is not None:
        folder = w.folder("cells")
        for k, centres in enumerate(cells):
            w.save(folder, f"frame_{k + 1:03d}.npy", centres)
        lines.append(f"wrote {folder}: frame_001.npy ... frame_{len(cells):03d}.npy (cell centres, um)")
    for first, last in pairs:
        name = f"{first}-{last}"
        folder = w.folder(name, "volumes")
        for frame in (first, last):
            w.link(os.path.join(out, "volumes", f"frame_{frame}.npy"), folder, f"frame_{frame}.npy")
        if cells is None:
            lines.append(f"wrote {os.path.join(out, name)}: volumes only; no cells without {CENTRES}")
        elif last > len(cells):
            lines.append(f"wrote {os.path.join(out, name)}: volumes only; {CENTRES} has {len(cells)} frames")
        else:
            folder = w.folder(name, "cells")
            for frame in (first, last):
                # cells/frame_{A:03d}.npy is frame A: the list counts from frame 1.
                w.save(folder, f"frame_{frame}.npy", cells[frame - 1])
            lines.append(f"wrote {os.path.join(out, name)}: volumes/ and cells/ of frames {first}, {last}")
    return lines


def main(data, out):
    if not os.path.isdir(data):
        raise Failure(f"no folder {data}")
    found = [p for p in PAIRS if os.path.isfile(os.path.join(data, pair_file(*p)))]
    has_centres = os.path.isfile(os.path.join(data, CENTRES))
    if not found and not has_centres:
        expected = ", ".join([pair_file(*p) for p in PAIRS] + [CENTRES])
        raise Failure(f"nothing to convert in {data}: expected any of {expected}")
    # Read and check everything first: a damaged file then stops the run before it writes.
    volumes = read_pairs(data, found)
    cells = read_checked(cell_centres, os.path.join(data, CENTRES)) if has_centres else None
    w = Writer(out)
    try:
        lines = write_all(w, volumes, found, cells)
    except OSError as e:
        w.drop_empty_folders()
        raise Failure(f"cannot write into {out}: {reason(e)}") from None
    missing = [pair_file(*p) for p in PAIRS if p not in found]
    if missing:
        lines.append(f"not found in {data}: {', '.join(missing)} (those pairs skipped)")
    if not has_centres:
        lines.append(f"not found in {data}: {CENTRES} (no cells written)")
    print("\n".join(lines))
    ready = [p for p in found if cells is not None and p[1] <= len(cells)]
    if ready:
        first, last = (140, 141) if (140, 141) in ready else ready[0]
        pair = os.path.join(out, f"{first}-{last}")
        voxel = ",".join(f"{v:g}" for v in VOXEL)
        print(f"next, e.g. for {first} -> {last}:")
        print(f"  meshflow surface {pair}/cells --out surf --vertices 65000")
        print(f"  meshflow sample {pair}/volumes surf --voxel-size {voxel}")
        print(f"  meshflow match {pair}/cells --out tracks.npy")
        print("  meshflow solve surf --out flow --regularizer strain --time-scale 0 "
              "--ground-truth-tracks tracks.npy --png")


if __name__ == "__main__":
    if len(sys.argv) == 2 and sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0)
    if len(sys.argv) != 3:
        sys.exit(USAGE)
    try:
        main(sys.argv[1], sys.argv[2])
    except Failure as e:
        sys.exit(f"{PROG}: {e}")
    except KeyboardInterrupt:
        sys.exit(f"{PROG}: interrupted")
