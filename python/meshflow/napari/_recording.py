"""The recording a surface was sampled from, opened lazily for napari: a dask array of its
frames, each read by the library when napari first shows it (:func:`meshflow.read_volumes`,
with the channel, pyramid level and placement ``meshflow sample`` used).

The library's readers, not tifffile or zarr-python, read it, so that every format ``meshflow
sample`` reads (NPY, TIFF stacks, ImageJ hyperstacks, OME-Zarr, directories of frames) opens
the same way, under the same file policy and memory limit; opening reads nothing, which keeps
a recording larger than memory (a 2.6 GB OME-Zarr) instant to open.
"""

from __future__ import annotations

from typing import Any, Dict

import numpy as np


def open_recording(recording: Dict[str, Any], n_frames: int):
    """``(n_frames, Z, Y, X)`` float32, lazy: frame ``k`` is read on first use (and the last two
    frames read are kept). A frame whose shape is no longer the recorded ``shape`` raises
    ``ValueError`` naming the path."""
    import dask
    import dask.array as da

    import functools

    shape = tuple(int(n) for n in recording["shape"])
    path = str(recording["path"])

    # napari asks for one plane at a time in 2-D; the library reads whole frames, so the last
    # two read are kept (a frame of a 2.6 GB recording of 20 frames is 130 MB).
    @functools.lru_cache(maxsize=2)
    def frame(k: int) -> np.ndarray:
        from .. import read_volumes

        read = read_volumes(
            path,
            voxel_size=recording["voxel_size"],
            origin=recording["origin"],
            channel=recording["channel"],
            resolution_level=recording["resolution_level"],
            frames=[k],
        )
        volume = read["volumes"][0]
        if volume.shape != shape:
            raise ValueError(
                f"{path}: frame {k} is {volume.shape} voxels (z, y, x), the surface was sampled "
                f"from {shape}: the recording changed since"
            )
        return volume

    frames = [da.from_delayed(dask.delayed(frame)(k), shape=shape, dtype=np.float32) for k in range(n_frames)]
    return da.stack(frames)
