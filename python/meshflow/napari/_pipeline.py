"""The microscopy pipeline the widget runs, without napari: surface → sample → solve →
analyze on a recording, written as a run that names the recording. Each step is the library
function the command line calls, so the result is the command line's:

=================================  ===================================================
this                               the command line
=================================  ===================================================
``shape="closed"``                 ``meshflow surface REC --shape closed --out SEQ``
``shape="sphere-like"``/``graph``  ``meshflow surface CELLS.npy --shape … --out SEQ``
sampling                           ``meshflow sample REC SEQ``
the flow                           ``meshflow solve SEQ --out RUN``
=================================  ===================================================

(with the same options: ``vertices``, ``smoothing`` as ``--vertices``, ``--smooth`` for a
closed surface and ``--smoothing`` through points, ``channel``, ``regularizer``,
``large_motion``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Sequence, Union

import numpy as np

#: The pipeline's steps, in order, as ``progress`` names them.
STEPS = ("surface", "sample", "solve", "analyze", "write")


class Cancelled(Exception):
    """The pipeline was asked to stop (by ``should_stop``)."""


@dataclass
class PipelineOptions:
    """The widget's options, each as the command line's flag of the same name."""

    shape: str = "closed"
    vertices: Optional[int] = None
    smoothing: Optional[float] = None
    channel: Optional[int] = None
    regularizer: str = "covariant"
    large_motion: Optional[bool] = None
    voxel_size: Optional[Sequence[float]] = None
    origin: Sequence[float] = (0.0, 0.0, 0.0)
    extra: Dict[str, Any] = field(default_factory=dict)


def flow_from_recording(
    recording: Union[str, PathLike],
    out: Union[str, PathLike],
    options: PipelineOptions = PipelineOptions(),
    *,
    cells: Optional[List[np.ndarray]] = None,
    progress: Optional[Callable[[Dict[str, Any]], Any]] = None,
    should_stop: Callable[[], bool] = lambda: False,
    force: bool = False,
) -> Dict[str, Any]:
    """Runs the pipeline (module docs) on the recording at ``recording`` and writes the flow's
    run to ``out`` (naming the recording, so that opening ``out`` in napari shows both).
    ``cells``: points per frame (N_k, 3) in ``(x, y, z)`` for a surface through them
    (``shape`` ``"sphere-like"`` or ``"graph"``). ``progress`` hears ``{"step": …}`` at each
    step and the solver's events; ``should_stop()`` is asked between steps and at every solver
    event, and raises :class:`Cancelled` when it says so. Returns ``flow``, ``sequence``
    (positions, faces, times), ``analysis`` and ``run`` (the path)."""
    import meshflow

    def step(name: str) -> None:
        if should_stop():
            raise Cancelled(name)
        if progress is not None:
            progress({"kind": "step", "step": name, "index": STEPS.index(name), "steps": len(STEPS)})

    def solver_event(event: Dict[str, Any]) -> None:
        if should_stop():
            raise Cancelled("solve")
        if progress is not None:
            progress(event)

    path = str(recording)
    step("surface")
    if options.shape == "closed":
        if cells is not None:
            raise ValueError("shape 'closed' finds the surface in the recording: give no cells")
        sequence = meshflow.closed_surface_sequence(
            path,
            options.voxel_size,
            origin=options.origin,
            channel=options.channel,
            vertices=options.vertices,
            smoothing=options.smoothing,
            progress=progress,
        )
        positions, faces, times = sequence.positions, sequence.faces, sequence.times
    else:
        if cells is None:
            raise ValueError(f"shape {options.shape!r} fits a surface through cells: give a points layer")
        fitted = meshflow.fit_surface(
            cells,
            options.shape,
            vertices=options.vertices,
            **({} if options.smoothing is None else {"smoothing": options.smoothing}),
        )
        positions, faces = fitted["positions"], fitted["faces"]
        times = np.arange(positions.shape[0], dtype=np.float64)
    step("sample")
    sampled = meshflow.sample_volume(
        path,
        positions,
        faces,
        options.voxel_size,
        origin=options.origin,
        channel=options.channel,
    )
    step("solve")
    flow = meshflow.compute_flow(
        positions,
        faces,
        sampled["values"],
        times,
        regularizer=options.regularizer,
        large_motion=options.large_motion,
        progress=solver_event,
        **options.extra,
    )
    step("analyze")
    analysis = meshflow.analyze(flow)
    step("write")
    record = {
        "path": path,
        "shape": list(sampled["shape"]),
        "voxel_size": list(sampled["voxel_size"]),
        "origin": list(sampled["origin"]),
        "channel": options.channel,
        "resolution_level": 0,
    }
    meshflow.write_outputs(flow, out, formats=["npy", "vtu"], force=force, recording=record)
    return {"flow": flow, "positions": positions, "faces": faces, "times": times, "analysis": analysis, "run": str(out)}
