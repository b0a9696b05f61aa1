"""napari's reader hook (npe2 ``readers``, ``accepts_directories``): a meshflow run directory,
recognized by its ``meshflow_run.json``, opens as its layers (:func:`._layers.run_layers`)."""

from __future__ import annotations

from pathlib import Path
from typing import Callable, List, Optional, Union

from ._layers import LayerData, run_layers

RUN_MANIFEST = "meshflow_run.json"


def napari_get_reader(path: Union[str, List[str]]) -> Optional[Callable[..., List[LayerData]]]:
    """The reader of ``path`` if it is one meshflow run directory (or its manifest), else
    ``None`` so that napari asks other readers."""
    if isinstance(path, list):
        if len(path) != 1:
            return None
        path = path[0]
    run = Path(path)
    if run.name == RUN_MANIFEST:
        run = run.parent
    if not (run.is_dir() and (run / RUN_MANIFEST).is_file()):
        return None
    return read_run_directory


def read_run_directory(path: Union[str, List[str]]) -> List[LayerData]:
    """The layers of the run at ``path`` (errors are the library's one-line messages)."""
    if isinstance(path, list):
        path = path[0]
    run = Path(path)
    if run.name == RUN_MANIFEST:
        run = run.parent
    return run_layers(run)
