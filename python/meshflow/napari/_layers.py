"""A meshflow run as napari layer data: ``(data, kwargs, layer_type)`` tuples, built with NumPy
alone (no napari import), so that the reader, :func:`meshflow.napari.show` and the tests share
one construction.

Coordinates. napari's world axes here are ``(t, z, y, x)``: ``t`` the frame index ``k`` (the
time slider's step; the frame times are in each layer's ``metadata["times"]``) and ``z, y,
x`` the surface's physical coordinates, i.e. meshflow's positions ``(x, y, z)`` reversed. A
recording sampled onto the surface (``meshflow sample``) opens as an Image with its voxel size
as ``scale`` and its origin as ``translate``, so the surface lies on the bright layer it was
read from (``docs/io.md`` of the repository: voxel ``(k, j, i)`` sits at ``o + (i d_x, j d_y,
k d_z)``).

Layers of a run (each only where the run has it):

=====================  ==========  ==========================================================
name                   type        from
=====================  ==========  ==========================================================
``surface``            Surface     the run's input, one mesh per frame, coloured by its image
``flow``               Vectors     ``flow.npy``: slab ``s``'s flow at frame ``s``'s vertices
``divergence`` …       Surface     ``analyze`` runs: ``divergence``, ``curl`` (per vertex),
                                   ``areal_rate`` (per face, area-averaged onto vertices)
``trajectories``       Tracks      ``advect`` runs: ``trajectories.npy``
``cells``              Points      ``track_errors.csv``: the scored cells, by endpoint error
``true displacement``  Vectors     ``track_errors.csv``: the cells' own displacement
``flow displacement``  Vectors     ``track_errors.csv``: the flow's displacement there
``recording``          Image       the recording the surface was sampled from (lazy)
=====================  ==========  ==========================================================
"""

from __future__ import annotations

import csv
import io
from os import PathLike
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

LayerData = Tuple[Any, Dict[str, Any], str]

#: The run's arrays the layers read (others are left on disk).
RUN_ARRAYS = [
    "flow.npy",
    "divergence.npy",
    "curl.npy",
    "areal_rate.npy",
    "trajectories.npy",
]
#: The run's text documents the layers read.
RUN_DOCUMENTS = ["summary.json", "track_errors.csv"]

#: The most arrows drawn per frame by default: about this many vertices, evenly spread.
DEFAULT_ARROWS = 4000
#: The most trajectories drawn by default (evenly chosen vertices).
DEFAULT_TRACKS = 2000
#: Below this fraction of the robust maximum a vector does not count as moving (the PNGs'
#: ``MOVING_FRACTION``).
MOVING_FRACTION = 0.1


def read_run(run: Union[str, PathLike]) -> Dict[str, Any]:
    """The run ``run`` as the library reads it (its file policy: the manifest checked, the
    surface from the recorded solve input, the run's own files only, sizes checked against
    the memory limit; ``meshflow.set_limits``)."""
    from .. import _meshflow

    return _meshflow.read_run(str(Path(run)), RUN_ARRAYS, RUN_DOCUMENTS)


def run_layers(
    run: Union[str, PathLike],
    *,
    arrows: Optional[int] = DEFAULT_ARROWS,
    tracks: Optional[int] = DEFAULT_TRACKS,
    recording: bool = True,
) -> List[LayerData]:
    """The layers of the run directory ``run`` (module docs). ``arrows``: about how many
    arrows per frame (``None``: one at every vertex); ``tracks``: how many trajectories at
    most (``None``: all); ``recording``: whether to open the recording the run names."""
    read = read_run(run)
    name = Path(run).resolve().name
    surface = Surface.of(read["surface"])
    arrays = read["arrays"]
    documents = read["documents"]
    layers: List[LayerData] = []
    if read["recording"] is not None and recording:
        layers.append(recording_layer(read["recording"], surface.n_frames, surface.grey))
    if read["command"] == "analyze":
        layers.extend(analysis_layers(surface, arrays, name))
    else:
        layers.append(surface.layer(f"{name}: surface"))
    if "flow.npy" in arrays:
        layers.append(flow_layer(surface, arrays["flow.npy"], f"{name}: flow", arrows))
    if "trajectories.npy" in arrays:
        layers.append(tracks_layer(surface, arrays["trajectories.npy"], f"{name}: trajectories", tracks))
    if "track_errors.csv" in documents:
        # The cells' displacements are drawn at the flow's scale (a displacement over a frame
        # spacing of 1 is that velocity's arrow), so the two compare on screen.
        flows = [kwargs["metadata"] for _, kwargs, kind in layers if kind == "vectors"]
        length = flows[0]["length"] if flows else 1.0
        size = 1.5 * (flows[0]["spacing"] if flows else arrow_spacing(surface, DEFAULT_ARROWS))
        layers.extend(cell_layers(documents["track_errors.csv"], name, length, size))
    return layers


class Surface:
    """A moving mesh in napari's coordinates: ``positions`` (K, V, 3) as ``(x, y, z)``,
    ``faces`` (F, 3), ``grey`` (K, V) or ``None``, ``times`` (K,), and ``first_file_vertex``
    (V,): for each mesh vertex one file vertex mapped to it, to read the run's per-file-vertex
    arrays at the mesh's vertices."""

    def __init__(self, positions, faces, grey, times, vertex_map):
        self.positions = np.asarray(positions, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.grey = grey
        self.times = np.asarray(times, dtype=np.float64)
        n_vertices = self.positions.shape[1]
        vertex_map = np.asarray(vertex_map, dtype=np.int64)
        self.first_file_vertex = first_file_vertex(vertex_map, n_vertices)

    @classmethod
    def of(cls, surface: Dict[str, Any]) -> "Surface":
        grey = surface["intensity"]
        if grey is not None and grey.ndim == 3:
            grey = grey.mean(axis=2)
        return cls(surface["positions"], surface["faces"], grey, surface["times"], surface["vertex_map"])

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    def at_mesh_vertices(self, per_file_vertex: np.ndarray) -> np.ndarray:
        """A run array ``(S, V_file, …)`` at the mesh's vertices ``(S, V, …)``."""
        return per_file_vertex[:, self.first_file_vertex]

    def vertices(self, frames: int) -> np.ndarray:
        """``(frames · V, 4)``: ``(k, z, y, x)`` of every vertex of the first ``frames`` frames."""
        k, v = frames, self.positions.shape[1]
        stamp = np.repeat(np.arange(k, dtype=np.float64), v)[:, None]
        return np.hstack([stamp, self.positions[:k, :, ::-1].reshape(k * v, 3)])

    def stacked_faces(self, frames: int) -> np.ndarray:
        v = self.positions.shape[1]
        offsets = (np.arange(frames, dtype=np.int64) * v)[:, None, None]
        return (self.faces[None, :, :] + offsets).reshape(-1, 3)

    def layer(self, name: str, values: Optional[np.ndarray] = None, **kwargs: Any) -> LayerData:
        """The Surface layer of the first ``len(values)`` frames (all, for the grey image)
        coloured by ``values`` (frames, V)."""
        if values is None:
            values = self.grey if self.grey is not None else np.zeros(self.positions.shape[:2])
            kwargs.setdefault("colormap", "gray")
            kwargs.setdefault("contrast_limits", robust_range(values))
        frames = values.shape[0]
        data = (self.vertices(frames), self.stacked_faces(frames), values.reshape(-1))
        metadata = {"times": self.times[:frames].tolist(), "meshflow": "surface"}
        return data, {"name": name, "metadata": metadata, **kwargs}, "surface"

    def area(self, frame: int = 0) -> float:
        p = self.positions[frame]
        f = self.faces
        return float(0.5 * np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]), axis=1).sum())

    def mean_edge_length(self) -> float:
        p = self.positions[0]
        f = self.faces
        edges = np.concatenate([p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 1]], p[f[:, 0]] - p[f[:, 2]]])
        return float(np.linalg.norm(edges, axis=1).mean())

    def face_to_vertex(self, per_face: np.ndarray, frame: int) -> np.ndarray:
        """Per-face values ``(F,)`` as vertex values: the area-weighted mean over each vertex's
        faces (napari colours vertices only)."""
        p = self.positions[frame]
        f = self.faces
        area = 0.5 * np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]), axis=1)
        n = p.shape[0]
        weighted = np.zeros(n)
        weights = np.zeros(n)
        for corner in range(3):
            np.add.at(weighted, f[:, corner], area * per_face)
            np.add.at(weights, f[:, corner], area)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(weights > 0, weighted / weights, np.nan)


def first_file_vertex(vertex_map: np.ndarray, n_vertices: int) -> np.ndarray:
    """For each of ``n_vertices`` mesh vertices the first file vertex mapped to it."""
    first = np.zeros(n_vertices, dtype=np.int64)
    kept = np.flatnonzero(vertex_map >= 0)[::-1]
    # Repeated indices: the last assignment wins, which (reversed) is the smallest file vertex.
    first[vertex_map[kept]] = kept
    return first


def robust_range(values: np.ndarray) -> Tuple[float, float]:
    """The 0.5th to 99.8th percentile of the finite ``values`` (a range wider than zero)."""
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return (0.0, 1.0)
    low, high = (float(p) for p in np.percentile(finite, [0.5, 99.8]))
    return (low, high) if high > low else (low, low + 1.0)


def symmetric_limits(values: np.ndarray) -> Tuple[float, float]:
    """``(−m, m)``, ``m`` the 99th percentile of ``|values|`` (a diverging colouring's range, as
    the analysis pictures draw it)."""
    finite = np.abs(values[np.isfinite(values)])
    top = float(np.percentile(finite, 99)) if finite.size else 0.0
    top = top if top > 0 else 1.0
    return (-top, top)


def robust_max(speeds: np.ndarray) -> float:
    """The 99th percentile of the finite speeds (the PNGs' saturation), positive."""
    finite = speeds[np.isfinite(speeds)]
    top = float(np.percentile(finite, 99)) if finite.size else 0.0
    return top if top > 0 else 1.0


def arrow_scale(speeds: np.ndarray) -> float:
    """The PNGs' reference arrow: the 75th percentile (nearest rank) of the moving speeds, those
    of at least :data:`MOVING_FRACTION` of :func:`robust_max`."""
    top = robust_max(speeds)
    moving = np.sort(speeds[np.isfinite(speeds) & (speeds >= MOVING_FRACTION * top)])
    if moving.size == 0:
        return top
    typical = moving[(3 * moving.size + 3) // 4 - 1]
    return float(min(typical, top)) if typical > 0 else top


def spread_vertices(points: np.ndarray, count: Optional[int], area: float) -> np.ndarray:
    """About ``count`` of ``points`` (V, 3), which sample a surface of ``area``, spread evenly
    over it: the first point in each cube of side ``√(area / count)``, the spacing of ``count``
    points on that area; all of them with ``None``."""
    n = points.shape[0]
    if count is None or count >= n:
        return np.arange(n)
    cell = np.sqrt(area / max(count, 1))
    keys = np.floor((points - points.min(axis=0)) / cell).astype(np.int64)
    _, chosen = np.unique(keys, axis=0, return_index=True)
    return np.sort(chosen)


def flow_layer(surface: Surface, flow: np.ndarray, name: str, arrows: Optional[int]) -> LayerData:
    """``flow.npy`` (S, V_file, 3) as napari vectors ``(N, 2, 4)``: at about ``arrows`` vertices
    of each frame ``s < S``, position ``(s, z, y, x)`` and projection ``(0, u_z, u_y, u_x)``.
    As in the PNGs, the reference arrow (:func:`arrow_scale`) is as long as the arrows'
    spacing, ``√(area / arrows drawn)``, so the typical arrow reaches its neighbour and the
    faster quarter overlaps. ``features`` hold each arrow's ``vertex``, ``slab`` and
    ``speed``; the arrows are one bright colour (speed is their length; colour them by the
    ``speed`` feature in napari's layer controls)."""
    vectors = surface.at_mesh_vertices(flow)
    slabs = vectors.shape[0]
    chosen = spread_vertices(surface.positions[0], arrows, surface.area())
    at = surface.positions[:slabs, chosen, ::-1]
    u = vectors[:, chosen, ::-1]
    n = len(chosen)
    stamps = np.repeat(np.arange(slabs, dtype=np.float64), n)[:, None]
    data = np.zeros((slabs * n, 2, 4))
    data[:, 0, 0] = stamps[:, 0]
    data[:, 0, 1:] = at.reshape(-1, 3)
    data[:, 1, 1:] = u.reshape(-1, 3)
    speed = np.linalg.norm(vectors, axis=2)
    spacing = arrow_spacing(surface, n)
    length = spacing / arrow_scale(speed.reshape(-1))
    features = {
        "vertex": np.tile(chosen, slabs),
        "slab": np.repeat(np.arange(slabs), n),
        "speed": speed[:, chosen].reshape(-1),
    }
    kwargs = {
        "name": name,
        "length": length,
        "vector_style": "arrow",
        "features": features,
        "edge_color": "cyan",
        "edge_width": 0.1 * spacing,
        "metadata": {
            "times": surface.times[:slabs].tolist(),
            "meshflow": "flow",
            "length": length,
            "spacing": spacing,
        },
    }
    return data, kwargs, "vectors"


def arrow_spacing(surface: Surface, arrows: int) -> float:
    """The spacing of ``arrows`` arrows spread over the surface's frame 0: ``√(area / arrows)``."""
    return float(np.sqrt(surface.area() / max(arrows, 1)))


def analysis_layers(surface: Surface, arrays: Dict[str, np.ndarray], name: str) -> List[LayerData]:
    """``analyze`` fields as alternative colourings of the surface (diverging, symmetric range):
    ``divergence`` and ``curl`` (per vertex), ``areal_rate`` (per face, area-averaged onto
    vertices); the first visible, the others hidden."""
    layers: List[LayerData] = []
    for field in ("divergence", "curl", "areal_rate"):
        stored = arrays.get(f"{field}.npy")
        if stored is None:
            continue
        if field == "areal_rate":
            values = np.stack([surface.face_to_vertex(stored[s], s) for s in range(stored.shape[0])])
        else:
            values = surface.at_mesh_vertices(stored)
        kwargs = {"colormap": "PiYG", "contrast_limits": symmetric_limits(values), "visible": not layers}
        layers.append(surface.layer(f"{name}: {field}", values, **kwargs))
    return layers


def tracks_layer(surface: Surface, trajectories: np.ndarray, name: str, most: Optional[int]) -> LayerData:
    """``trajectories.npy`` (K, N, 3) as napari tracks ``(track, t, z, y, x)``, at most ``most``
    of them (evenly chosen over frame 0)."""
    frames, n, _ = trajectories.shape
    chosen = spread_vertices(trajectories[0], most, surface.area())
    points = trajectories[:, chosen, ::-1]
    ids = np.tile(np.arange(len(chosen)), frames)
    stamps = np.repeat(np.arange(frames), len(chosen))
    data = np.column_stack([ids, stamps, points.reshape(-1, 3)])
    finite = np.all(np.isfinite(data), axis=1)
    data = data[finite]
    data = data[np.lexsort((data[:, 1], data[:, 0]))]
    kwargs = {
        "name": name,
        "tail_length": max(frames, 2),
        "metadata": {"times": surface.times.tolist(), "meshflow": "trajectories", "seeds": chosen.tolist()},
    }
    return data, kwargs, "tracks"


def cell_layers(text: str, name: str, length: float = 1.0, size: float = 4.0) -> List[LayerData]:
    """``track_errors.csv``: the scored cells as Points of ``size`` at ``(s, z, y, x)``
    coloured by their endpoint error, and their true and computed displacements as two
    Vectors layers drawn ``length`` times their size."""
    rows = list(csv.DictReader(io.StringIO(text)))
    if not rows:
        return []

    def column(key: str) -> np.ndarray:
        return np.array([float(r[key]) if r[key] != "" else np.nan for r in rows])

    frame = column("frame")
    at = np.column_stack([frame, column("z"), column("y"), column("x")])
    true = np.column_stack([np.zeros(len(rows)), column("true_z"), column("true_y"), column("true_x")])
    computed = np.column_stack([np.zeros(len(rows)), column("flow_z"), column("flow_y"), column("flow_x")])
    error = column("endpoint_error")
    features = {
        "track": column("track"),
        "endpoint_error": error,
        "direction_error_degrees": column("direction_error_degrees"),
        "speed_ratio": column("speed_ratio"),
    }
    points = (
        at,
        {
            "name": f"{name}: cells",
            "features": features,
            "face_color": "endpoint_error",
            "face_colormap": "magma",
            "size": size,
            "metadata": {"meshflow": "cells"},
        },
        "points",
    )

    def displacement(vectors: np.ndarray, label: str, color: str) -> LayerData:
        data = np.stack([at, vectors], axis=1)
        kwargs = {
            "name": f"{name}: {label}",
            "edge_color": color,
            "length": length,
            "vector_style": "arrow",
            "metadata": {"meshflow": label},
        }
        return data, kwargs, "vectors"

    return [points, displacement(true, "true displacement", "white"), displacement(computed, "flow displacement", "orange")]


def recording_layer(recording: Dict[str, Any], n_frames: int, grey: Optional[np.ndarray]) -> LayerData:
    """The recording the surface was sampled from (``n_frames`` frames, as the surface, whose
    ``grey`` values were sampled from it), opened lazily (:mod:`._recording`), with
    ``scale`` ``(1, d_z, d_y, d_x)`` and ``translate`` ``(0, o_z, o_y, o_x)``."""
    from ._recording import open_recording

    data = open_recording(recording, n_frames)
    # The contrast of the values sampled from it onto the surface (its bright layer and the
    # dark between): opening then reads nothing, and napari's first draw reads one frame.
    contrast = robust_range(grey) if grey is not None else None
    dx, dy, dz = recording["voxel_size"]
    ox, oy, oz = recording["origin"]
    kwargs = {
        "name": f"{Path(recording['path']).name}",
        "scale": (1.0, dz, dy, dx),
        "translate": (0.0, oz, oy, ox),
        "colormap": "gray",
        **({} if contrast is None else {"contrast_limits": contrast}),
        "blending": "additive",
        "rendering": "mip",
        "metadata": {"meshflow": "recording", "path": str(recording["path"])},
    }
    return data, kwargs, "image"
