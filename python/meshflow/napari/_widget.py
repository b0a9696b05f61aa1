"""The dock widget: the microscopy pipeline (:mod:`._pipeline`) run on what is open in the
viewer, an Image layer (a 4-D stack) with or without a Points layer of cells.

The pipeline runs in a worker thread (napari's ``create_worker``); the library releases
Python's lock during every long step, so the viewer stays responsive. Progress goes to
napari's activity dock (a ``napari.utils.progress`` bar of the five steps, its description
the solver's latest iteration) and to the log (``logging``, logger ``meshflow.napari``).
*Cancel* asks the pipeline to stop: the solve stops within one iteration (the library checks
its progress callback at each one), the other steps at their end. The results come back as
the reader's layers of the run written to *output*, with the analysis fields beside them.

Where the Image layer was opened from a file (``layer.source.path``), that file is the
recording; otherwise its data are saved as ``<output>.recording.npy`` beside the output
first. Its voxel size and origin are the layer's ``scale`` and ``translate`` (their last three
axes, ``z, y, x``), where not all 1 and 0; else the file's metadata.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, List, Optional

import numpy as np

from ._layers import Surface, analysis_layers, read_run, run_layers
from ._pipeline import STEPS, Cancelled, PipelineOptions, flow_from_recording

if TYPE_CHECKING:
    import napari

log = logging.getLogger("meshflow.napari")

SHAPES = ["closed", "sphere-like", "graph"]
REGULARIZERS = ["covariant", "strain", "embedded"]
LARGE_MOTION = {"auto": None, "on": True, "off": False}


def cells_by_frame(points: np.ndarray, n_frames: int) -> List[np.ndarray]:
    """A Points layer's ``(N, 4)`` rows ``(t, z, y, x)`` as points per frame ``(N_k, 3)`` in
    meshflow's ``(x, y, z)``."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 4:
        raise ValueError(f"the cells layer holds {points.shape} points: expected (N, 4) as (t, z, y, x)")
    frames = np.rint(points[:, 0]).astype(np.int64)
    return [points[frames == k, 1:][:, ::-1] for k in range(n_frames)]


def placement(layer: Any) -> Dict[str, Any]:
    """The voxel size and origin ``(x, y, z)`` of an Image layer from its ``scale`` and
    ``translate`` (``None`` voxel size where they are the defaults: the file says)."""
    scale = np.asarray(layer.scale, dtype=np.float64)[-3:][::-1]
    translate = np.asarray(layer.translate, dtype=np.float64)[-3:][::-1]
    voxel_size = None if np.allclose(scale, 1.0) else tuple(scale)
    return {"voxel_size": voxel_size, "origin": tuple(translate)}


def recording_path(layer: Any, out: Path) -> Path:
    """The recording behind ``layer``: the file it was opened from, or its data saved beside
    ``out`` (module docs)."""
    source = getattr(getattr(layer, "source", None), "path", None)
    if source is not None and Path(source).exists():
        return Path(source)
    saved = out.parent / f"{out.name}.recording.npy"
    data = np.asarray(layer.data, dtype=np.float32)
    if data.ndim != 4:
        raise ValueError(f"{layer.name}: {data.shape} voxels: the widget needs a 4-D stack (t, z, y, x)")
    np.save(saved, data)
    return saved


def make_widget(napari_viewer: "napari.viewer.Viewer"):
    """The widget for ``napari_viewer``: a magicgui ``Container`` whose ``.native`` napari
    docks (npe2 command ``meshflow.pipeline_widget``). ``run_button``, ``cancel_button``,
    ``status`` and ``controls`` (by option name) are there for scripts and tests."""
    from magicgui.widgets import ComboBox, Container, FileEdit, FloatSpinBox, Label, PushButton, SpinBox

    import napari

    viewer = napari_viewer
    image = ComboBox(label="stack", choices=lambda _: [l for l in viewer.layers if isinstance(l, napari.layers.Image)])
    cells = ComboBox(
        label="cells",
        nullable=True,
        choices=lambda _: [l for l in viewer.layers if isinstance(l, napari.layers.Points)],
    )
    shape = ComboBox(label="shape", choices=SHAPES, value="closed")
    vertices = SpinBox(label="vertices (0: default)", min=0, max=10_000_000, value=0)
    smoothing = FloatSpinBox(label="smoothing (0: default)", min=0.0, max=1e6, value=0.0, step=0.1)
    channel = SpinBox(label="channel (-1: default)", min=-1, max=1000, value=-1)
    regularizer = ComboBox(label="regularizer", choices=REGULARIZERS, value="covariant")
    large_motion = ComboBox(label="large motion", choices=list(LARGE_MOTION), value="auto")
    out = FileEdit(label="output", mode="d", value=str(Path.cwd() / "meshflow-run"))
    run = PushButton(text="Run")
    cancel = PushButton(text="Cancel", enabled=False)
    status = Label(value="")
    container = Container(
        widgets=[image, cells, shape, vertices, smoothing, channel, regularizer, large_motion, out, run, cancel, status]
    )
    container.state = _State()

    def refresh(_: Any = None) -> None:
        image.reset_choices()
        cells.reset_choices()

    viewer.layers.events.inserted.connect(refresh)
    viewer.layers.events.removed.connect(refresh)

    def options() -> PipelineOptions:
        place = placement(image.value)
        return PipelineOptions(
            shape=shape.value,
            vertices=vertices.value or None,
            smoothing=smoothing.value or None,
            channel=None if channel.value < 0 else channel.value,
            regularizer=regularizer.value,
            large_motion=LARGE_MOTION[large_motion.value],
            voxel_size=place["voxel_size"],
            origin=place["origin"],
        )

    def start() -> None:
        if image.value is None:
            status.value = "open a 4-D stack (an Image layer) first"
            return
        target = Path(out.value)
        n_frames = int(np.asarray(image.value.data.shape)[0])
        points = None if cells.value is None else cells_by_frame(cells.value.data, n_frames)
        chosen = options()
        recording = recording_path(image.value, target)
        container.state.begin()
        run.enabled, cancel.enabled = False, True
        worker = container.state.start(recording, target, chosen, points)
        worker.returned.connect(finished)
        worker.errored.connect(failed)
        worker.start()

    def finished(result: Dict[str, Any]) -> None:
        container.state.end()
        if "cancelled" in result:
            run.enabled, cancel.enabled = True, False
            status.value = "cancelled"
            log.info("meshflow: cancelled during %s", result["cancelled"])
            return
        layers = result_layers(result)
        for data, kwargs, kind in layers:
            getattr(viewer, f"add_{kind}")(data, **kwargs)
        run.enabled, cancel.enabled = True, False
        status.value = f"done: {result['run']}"
        log.info("meshflow: the run is in %s", result["run"])

    def failed(error: BaseException) -> None:
        container.state.end()
        run.enabled, cancel.enabled = True, False
        status.value = f"failed: {error}"
        log.warning("meshflow: %s", status.value)

    def stop() -> None:
        container.state.stop.set()
        status.value = "cancelling…"

    run.changed.connect(start)
    cancel.changed.connect(stop)
    container.run_button, container.cancel_button, container.status = run, cancel, status
    container.controls = {
        "image": image, "cells": cells, "shape": shape, "vertices": vertices, "smoothing": smoothing,
        "channel": channel, "regularizer": regularizer, "large_motion": large_motion, "out": out,
    }
    return container


class _State:
    """The running pipeline: its stop flag, napari progress bar and worker."""

    def __init__(self) -> None:
        self.stop = threading.Event()
        self.bar = None
        self.worker = None
        #: The step running now (``None`` before the first and after the last).
        self.step: Optional[str] = None

    def begin(self) -> None:
        from napari.utils import progress

        self.stop.clear()
        self.step = "starting"
        self.bar = progress(total=len(STEPS), desc="meshflow")

    def end(self) -> None:
        self.step = None
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def start(self, recording: Path, out: Path, options: PipelineOptions, cells: Optional[List[np.ndarray]]):
        from napari.qt.threading import create_worker
        from qtpy.QtCore import QObject, Signal

        class Relay(QObject):
            event = Signal(object)

        relay = Relay()
        relay.event.connect(self.show)
        self.relay = relay

        def report(event: Dict[str, Any]) -> None:
            relay.event.emit(dict(event))

        def work() -> Dict[str, Any]:
            log.info("meshflow: %s -> %s", recording, out)
            try:
                return flow_from_recording(
                    recording, out, options, cells=cells, progress=report, should_stop=self.stop.is_set, force=True
                )
            except Cancelled as stopped:
                # A result, not an error: napari would report an error as a failure.
                return {"cancelled": str(stopped)}

        self.worker = create_worker(work)
        return self.worker

    def show(self, event: Dict[str, Any]) -> None:
        """One progress event, in the main thread: the bar and the log."""
        if self.bar is None:
            return
        kind = event.get("kind")
        if kind == "step":
            self.step = event["step"]
            self.bar.n = event["index"]
            self.bar.set_description(f"meshflow: {event['step']}")
            self.bar.refresh()
            log.info("meshflow: %s", event["step"])
        elif kind == "iteration":
            self.bar.set_description(f"meshflow: solve, iteration {event['iteration']}, residual {event['relative_residual']:.1e}")
        elif kind == "surface":
            self.bar.set_description(f"meshflow: surface, frame {event['frame'] + 1} of {event['frames']}")
            log.info("meshflow: surface of frame %d of %d", event["frame"] + 1, event["frames"])


def result_layers(result: Dict[str, Any]) -> list:
    """The layers of a finished pipeline: the run's (the reader's), and the analysis fields."""
    run = Path(result["run"])
    layers = run_layers(run, recording=False)
    surface = Surface.of(read_run(run)["surface"])
    arrays = {f"{name}.npy": np.asarray(value) for name, value in result["analysis"].items() if name in ("divergence", "curl", "areal_rate")}
    layers.extend(analysis_layers(surface, arrays, run.name))
    return layers
