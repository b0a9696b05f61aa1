"""napari's writer hook (npe2 ``writers``): a time-lapse Surface layer, with a flow Vectors
layer where one is selected too, saved as a meshflow NPY sequence (positions.npy, faces.npy,
intensity.npy, times.txt: what ``meshflow solve DIR`` reads) with ``surface_KKKK.vtu`` and
``surface.pvd`` for ParaView, staged and renamed into place whole.

A Surface layer is a moving mesh when its vertices are ``(t, z, y, x)`` and every frame ``t =
k`` holds the same number of vertices with the same faces (as this plugin's reader and
napari-stress's time-lapse surfaces build them). Vectors ``(N, 2, 4)`` are placed at the
vertices they start from: by their ``vertex`` feature (this plugin's flow layers), else at the
frame's vertex they sit on.
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from ._layers import LayerData


def write_layers(path: str, layer_data: List[LayerData]) -> List[str]:
    """Writes the one Surface layer of ``layer_data`` (and a Vectors layer, if any) to the
    directory ``path``; returns ``[path]``. Errors are ``ValueError`` naming what is wrong."""
    from .. import _meshflow

    surfaces = [d for d in layer_data if d[2] == "surface"]
    if len(surfaces) != 1:
        raise ValueError(f"select one surface layer to write as a meshflow sequence, got {len(surfaces)}")
    data, meta, _ = surfaces[0]
    positions, faces, values = split_frames(data, meta.get("name", "surface"))
    times = (meta.get("metadata") or {}).get("times")
    if times is None or len(times) != positions.shape[0]:
        times = list(range(positions.shape[0]))
    vectors = None
    flows = [d for d in layer_data if d[2] == "vectors"]
    if flows:
        vectors = vectors_at_vertices(flows[0], positions)
    _meshflow.write_sequence(
        str(path), positions, faces, values, [float(t) for t in times], vectors, False
    )
    return [str(path)]


def split_frames(data: Tuple[Any, ...], name: str) -> Tuple[np.ndarray, np.ndarray, Optional[np.ndarray]]:
    """A time-lapse surface's ``(vertices (K·V, 4), faces (K·F, 3)[, values])`` as positions
    ``(K, V, 3)`` in meshflow's ``(x, y, z)``, frame 0's faces ``(F, 3)`` and values ``(K, V)``."""
    vertices = np.asarray(data[0], dtype=np.float64)
    faces = np.asarray(data[1], dtype=np.int64)
    values = np.asarray(data[2], dtype=np.float64) if len(data) > 2 and data[2] is not None else None
    if vertices.ndim != 2 or vertices.shape[1] != 4:
        raise ValueError(f"{name}: vertices are {vertices.shape}, expected (frames · vertices, 4) as (t, z, y, x)")
    stamps = vertices[:, 0]
    frames = np.unique(stamps)
    k = len(frames)
    if k < 2:
        raise ValueError(f"{name}: one frame: a meshflow sequence needs 2 frames at least")
    if vertices.shape[0] % k:
        raise ValueError(f"{name}: {vertices.shape[0]} vertices do not split into {k} frames of one size")
    v = vertices.shape[0] // k
    expected = np.repeat(frames, v)
    if not np.array_equal(stamps, expected):
        raise ValueError(f"{name}: the vertices are not grouped by frame, each frame the same count")
    if faces.shape[0] % k:
        raise ValueError(f"{name}: {faces.shape[0]} faces do not split into {k} frames of one mesh")
    f = faces.shape[0] // k
    first = faces[:f]
    for frame in range(1, k):
        if not np.array_equal(faces[frame * f : (frame + 1) * f] - frame * v, first):
            raise ValueError(f"{name}: frame {frame} has other faces than frame 0: not one moving mesh")
    positions = vertices[:, 1:][:, ::-1].reshape(k, v, 3).copy()
    grey = None
    if values is not None:
        if values.ndim != 1 or values.shape[0] != k * v:
            raise ValueError(f"{name}: values are {values.shape}, expected one per vertex ({k * v})")
        grey = values.reshape(k, v).copy()
    return positions, first, grey


def vectors_at_vertices(layer: LayerData, positions: np.ndarray) -> np.ndarray:
    """A Vectors layer ``(N, 2, 4)`` as ``(S, V, 3)`` flow vectors in ``(x, y, z)`` at the
    surface's vertices (NaN where none starts), ``S`` its frames."""
    data, meta, _ = layer
    data = np.asarray(data, dtype=np.float64)
    name = meta.get("name", "vectors")
    if data.ndim != 3 or data.shape[1:] != (2, 4):
        raise ValueError(f"{name}: vectors are {data.shape}, expected (N, 2, 4) as (t, z, y, x)")
    features: Dict[str, Any] = meta.get("features") or {}
    slabs = data[:, 0, 0].astype(np.int64)
    k, v = positions.shape[:2]
    if slabs.min() < 0 or slabs.max() >= k:
        raise ValueError(f"{name}: vectors at frames beyond the surface's {k}")
    out = np.full((int(slabs.max()) + 1, v, 3), np.nan)
    u = data[:, 1, 1:][:, ::-1]
    if "vertex" in features:
        # This plugin's flow layers say where each arrow starts.
        vertex = np.asarray(features["vertex"], dtype=np.int64)
    else:
        from scipy.spatial import cKDTree

        vertex = np.empty(len(data), dtype=np.int64)
        for s in np.unique(slabs):
            on = slabs == s
            at = data[on, 0, 1:][:, ::-1]
            vertex[on] = cKDTree(positions[s]).query(at)[1]
    out[slabs, vertex] = u
    return out
