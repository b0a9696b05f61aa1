"""How long napari takes to open meshflow runs (the plugin's targets: a 20-frame, 94k-vertex
run in ≤ 5 s; a 2.6 GB OME-Zarr recording beside it in ≤ 2 s, lazily).

    xvfb-run -a python python/benchmarks/napari_open.py [DIR]     (needs "./python[napari]")

Makes, under DIR (default ``out/napari_open``; reused when there):

- ``torus``: a 400 × 235 torus grid (94,000 vertices, 20 frames) breathing while a texture
  moves over it, solved with the defaults (``meshflow.compute_flow``), written with
  ``write_outputs`` (NPY);
- ``recording.zarr``: an OME-Zarr image (NGFF 0.4, Zarr v2, Blosc-compressed float32) of
  20 × 160 × 450 × 450 voxels, 2.59 GB uncompressed, and ``shell``: a run on a small sphere
  that names it as its recording.

Then prints, each the median of three: the plugin's layers read (``run_layers``), and
``viewer.open`` until the viewer has drawn them (a shown viewer, so under Xvfb in CI).
"""

import pathlib
import statistics
import sys
import time

import numpy as np

import meshflow
from meshflow.napari import _layers

ROOT = pathlib.Path(__file__).resolve().parents[2]
FRAMES = 20


def torus_run(directory: pathlib.Path) -> pathlib.Path:
    run = directory / "torus"
    if (run / "flow.npy").is_file():
        return run
    n1, n2 = 400, 235
    u, v = np.meshgrid(np.arange(n1) * 2 * np.pi / n1, np.arange(n2) * 2 * np.pi / n2, indexing="ij")
    index = np.arange(n1 * n2).reshape(n1, n2)
    a, b, c, d = index, np.roll(index, -1, 0), np.roll(np.roll(index, -1, 0), -1, 1), np.roll(index, -1, 1)
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    positions, grey = [], []
    for k in range(FRAMES):
        r = 1.0 + 0.05 * np.sin(0.3 * k)
        x = (3 + r * np.cos(v)) * np.cos(u)
        y = (3 + r * np.cos(v)) * np.sin(u)
        z = r * np.sin(v)
        positions.append(np.stack([x, y, z], -1).reshape(-1, 3))
        grey.append((np.sin(12 * (u - 0.01 * k)) * np.cos(7 * v + 0.02 * k)).reshape(-1))
    flow = meshflow.compute_flow(np.array(positions), faces, np.array(grey))
    meshflow.write_outputs(flow, run, formats=["npy"])
    return run


def zarr_run(directory: pathlib.Path) -> pathlib.Path:
    import zarr

    store = directory / "recording.zarr"
    shape = (FRAMES, 160, 450, 450)
    if not (store / ".zattrs").is_file():
        root = zarr.open_group(str(store), mode="w", zarr_format=2)
        array = root.create_array("0", shape=shape, chunks=(1, 32, 150, 150), dtype="float32")
        z, y, x = np.meshgrid(np.arange(160), np.arange(450), np.arange(450), indexing="ij")
        for k in range(FRAMES):
            array[k] = (np.sin(x / 9.0 + 0.1 * k) * np.cos(y / 7.0) + z / 160.0).astype(np.float32)
        axes = [{"name": "t", "type": "time"}] + [{"name": n, "type": "space"} for n in "zyx"]
        transform = [{"type": "scale", "scale": [1.0, 2.0, 0.5, 0.5]}]
        root.attrs["multiscales"] = [
            {"version": "0.4", "axes": axes, "datasets": [{"path": "0", "coordinateTransformations": transform}]}
        ]
    run = directory / "shell"
    if not (run / "meshflow_run.json").is_file():
        points, faces = meshflow_icosphere()
        positions = np.stack([points * 60 + [112, 112, 160] for _ in range(FRAMES)])
        grey = np.stack([np.sin(3 * points[:, 0] + 0.1 * k) for k in range(FRAMES)])
        flow = meshflow.compute_flow(positions, faces, grey)
        recording = {"path": store, "shape": shape[1:], "voxel_size": (0.5, 0.5, 2.0), "origin": (0, 0, 0)}
        meshflow.write_outputs(flow, run, formats=["npy"], recording=recording)
    return run


def meshflow_icosphere():
    from meshflow.napari._sample_data import icosphere

    return icosphere(4)


def timed(action, repeats=3):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    directory = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "out" / "napari_open"
    directory.mkdir(parents=True, exist_ok=True)
    torus, shell = torus_run(directory), zarr_run(directory)
    import napari
    from qtpy.QtWidgets import QApplication

    for name, run in (("torus, 94,000 vertices × 20 frames", torus), ("2.6 GB OME-Zarr beside a run", shell)):
        layers = timed(lambda: _layers.run_layers(run))
        viewer = napari.Viewer(show=True)

        def open_and_draw():
            viewer.layers.clear()
            viewer.open(str(run), plugin="meshflow")
            QApplication.processEvents()
            viewer.window._qt_viewer.canvas.native.update()
            QApplication.processEvents()

        opened = timed(open_and_draw)
        viewer.close()
        print(f"{name}: layers read {layers:.2f} s, viewer.open and first draw {opened:.2f} s")


if __name__ == "__main__":
    main()
