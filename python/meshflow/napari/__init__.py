"""meshflow in napari: a run seen over its recording, and the pipeline run from the viewer.

Install with ``pip install "./python[napari]"`` (napari, magicgui, qtpy; bring your own Qt
backend, e.g. ``pip install pyqt6``). Then:

- ``viewer.open("out/run")`` (or *File → Open Folder*) on a directory that ``meshflow solve``,
  ``analyze``, ``advect``, ``track`` or ``surface`` wrote gives its layers (:mod:`._layers`:
  the moving surface, the flow's arrows, analysis colourings, trajectories, scored cells and
  the recording, in the recording's physical coordinates);
- *Plugins → meshflow: flow from a recording* docks the widget that runs surface → sample →
  solve → analyze on an open 4-D Image layer (:mod:`._widget`);
- *File → Save Selected Layers* with a surface (and flow vectors) writes a meshflow sequence
  with VTU/PVD files for ParaView (:mod:`._writer`);
- *File → Open Sample → meshflow* opens a turning sphere or a synthetic shell stack, each with
  its run (:mod:`._sample_data`).

From Python or a notebook, :func:`show` does the same without the plugin menus.
"""

from __future__ import annotations

from os import PathLike
from typing import Any, List, Optional, Union

from ._layers import DEFAULT_ARROWS, DEFAULT_TRACKS, LayerData, run_layers

__all__ = ["show", "run_layers", "layers_of_flow", "LayerData"]


def layers_of_flow(flow: Any, name: str = "flow", arrows: Optional[int] = DEFAULT_ARROWS) -> List[LayerData]:
    """The layers of a :class:`meshflow.Flow` computed in Python: written as a run (NPY only,
    into a temporary directory, which holds the sequence too) and read back as
    :func:`run_layers` reads any run, so that a flow shows as its run would."""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory(prefix="meshflow-napari-") as scratch:
        run = Path(scratch) / name
        flow.write(str(run), ["npy"], False)
        return run_layers(run, arrows=arrows, recording=False)


def show(
    run_or_flow: Union[str, PathLike, Any],
    viewer: Any = None,
    *,
    arrows: Optional[int] = DEFAULT_ARROWS,
    tracks: Optional[int] = DEFAULT_TRACKS,
    recording: bool = True,
):
    """Shows a run directory (or a :class:`meshflow.Flow`) in ``viewer`` (a new napari viewer
    when ``None``) in 3-D, and returns the viewer. Keywords as :func:`run_layers`."""
    import napari

    if viewer is None:
        viewer = napari.Viewer(ndisplay=3)
    if isinstance(run_or_flow, (str, PathLike)):
        layers = run_layers(run_or_flow, arrows=arrows, tracks=tracks, recording=recording)
    else:
        layers = layers_of_flow(run_or_flow, arrows=arrows)
    add_layers(viewer, layers)
    viewer.dims.ndisplay = 3
    return viewer


def add_layers(viewer: Any, layers: List[LayerData]) -> list:
    """Adds ``(data, kwargs, type)`` tuples to ``viewer``; returns the layers."""
    added = []
    for data, kwargs, kind in layers:
        added.append(getattr(viewer, f"add_{kind}")(data, **kwargs))
    return added
