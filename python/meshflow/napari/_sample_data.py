"""napari's sample data (npe2 ``sample_data``): two small scenes computed on the spot, each
written as a meshflow run and opened as the reader opens runs, so that a new user sees the
plugin work in one click (a few seconds).

- :func:`rotating_sphere`: a smooth texture turning about z on an icosphere (642 vertices,
  6 frames, 0.05 rad per frame), the shipped sample ``meshes/rotating_sphere`` of the
  repository made again in NumPy;
- :func:`turning_shell`: a synthetic 4-D stack (6 frames of 48 × 56 × 56 voxels, voxels
  1 × 1 × 1.5) of a bright spotted shell turning about its axis, run through the pipeline
  of the widget (closed surface → sample → solve), with the stack beside it.

The runs are written under ``$MESHFLOW_SAMPLES`` (default: ``meshflow-napari-samples`` in the
user's cache directory), replacing the previous ones.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import List, Tuple

import numpy as np

from ._layers import LayerData, run_layers

#: The shell's turn per frame (radians about z): 0.7 voxels a frame at its equator.
SHELL_TURN = 0.7 / 17.0
#: The sphere's texture turn per frame (radians about z), as the shipped sample.
SPHERE_TURN = 0.05


def samples_dir() -> Path:
    """Where the sample runs are written (module docs)."""
    given = os.environ.get("MESHFLOW_SAMPLES")
    if given:
        return Path(given)
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "meshflow-napari-samples"


def icosphere(subdivisions: int = 3) -> Tuple[np.ndarray, np.ndarray]:
    """The unit icosphere: ``10·4^n + 2`` vertices, faces counter-clockwise from outside."""
    t = (1.0 + 5.0**0.5) / 2.0
    vertices = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
                (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    points = [np.array(v, dtype=np.float64) / np.linalg.norm(v) for v in vertices]
    for _ in range(subdivisions):
        middle = {}

        def midpoint(a: int, b: int) -> int:
            key = (min(a, b), max(a, b))
            if key not in middle:
                m = points[a] + points[b]
                points.append(m / np.linalg.norm(m))
                middle[key] = len(points) - 1
            return middle[key]

        finer = []
        for a, b, c in faces:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            finer += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = finer
    return np.array(points), np.array(faces, dtype=np.int64)


def turned(points: np.ndarray, angle: float) -> np.ndarray:
    """``points`` (…, 3) turned by ``angle`` about z."""
    c, s = np.cos(angle), np.sin(angle)
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return np.stack([c * x - s * y, s * x + c * y, z], axis=-1)


def sphere_texture(points: np.ndarray) -> np.ndarray:
    """A smooth grey pattern on the unit sphere."""
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return 0.5 + 0.25 * np.sin(3 * x + 1) * np.cos(2 * y) + 0.2 * np.sin(4 * z + 2 * x)


def rotating_sphere() -> List[LayerData]:
    """The rotating sphere's run (module docs), opened as its layers."""
    import meshflow

    points, faces = icosphere(3)
    frames = 6
    positions = np.repeat(points[None], frames, axis=0)
    grey = np.stack([sphere_texture(turned(points, -SPHERE_TURN * k)) for k in range(frames)])
    flow = meshflow.compute_flow(positions, faces, grey)
    run = samples_dir() / "rotating_sphere"
    run.parent.mkdir(parents=True, exist_ok=True)
    meshflow.write_outputs(flow, run, formats=["npy", "vtu"])
    return run_layers(run)


def shell_stack(frames: int = 6, shape: Tuple[int, int, int] = (48, 56, 56),
                voxel_size: Tuple[float, float, float] = (1.0, 1.0, 1.5)) -> np.ndarray:
    """A bright shell (radius 17, 1.5 thick) with 24 spots turning about z by
    :data:`SHELL_TURN` a frame, ``(frames, Z, Y, X)`` float32 for ``voxel_size`` ``(x, y, z)``."""
    nz, ny, nx = shape
    dx, dy, dz = voxel_size
    z, y, x = np.meshgrid(np.arange(nz) * dz, np.arange(ny) * dy, np.arange(nx) * dx, indexing="ij")
    centre = np.array([(nx - 1) * dx, (ny - 1) * dy, (nz - 1) * dz]) / 2.0
    p = np.stack([x - centre[0], y - centre[1], z - centre[2]], axis=-1)
    r = np.linalg.norm(p, axis=-1)
    shell = np.exp(-((r - 17.0) ** 2) / (2 * 1.5**2))
    spots = np.random.default_rng(7).normal(size=(24, 3))
    spots /= np.linalg.norm(spots, axis=1, keepdims=True)
    direction = p / np.maximum(r, 1e-9)[..., None]
    stack = np.empty((frames, nz, ny, nx), dtype=np.float32)
    for k in range(frames):
        moved = turned(spots, SHELL_TURN * k)
        cosines = np.tensordot(direction, moved.T, axes=1)
        texture = 0.3 + np.exp((cosines - 1.0) / 0.02).sum(axis=-1)
        stack[k] = (shell * texture).astype(np.float32)
    return stack


def turning_shell() -> List[LayerData]:
    """The turning shell's stack and run (module docs), opened as the reader opens them."""
    from ._pipeline import PipelineOptions, flow_from_recording

    directory = samples_dir() / "turning_shell"
    directory.mkdir(parents=True, exist_ok=True)
    stack = directory / "shell.npy"
    voxel_size = (1.0, 1.0, 1.5)
    np.save(stack, shell_stack(voxel_size=voxel_size))
    run = directory / "run"
    options = PipelineOptions(shape="closed", voxel_size=voxel_size, vertices=2000)
    flow_from_recording(stack, run, options)
    return run_layers(run)
