"""Type stubs of the compiled half of meshflow (see ``meshflow/__init__.py`` for the API)."""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

class Flow:
    """A computed flow, in the input's vertex numbering (NaN at dropped vertices).

    ``S = K − 1`` slabs; slab ``s`` is the motion from frame ``s`` to ``s + 1``.
    """

    @property
    def vectors(self) -> Optional[npt.NDArray[np.float64]]:
        """(S, V, 3): the flow of slab ``s`` in R³ at the vertices of frame ``s``."""
    @property
    def intrinsic(self) -> npt.NDArray[np.float64]:
        """(S, V, 2): the same in the vertex frames."""
    @property
    def frames(self) -> npt.NDArray[np.float64]:
        """(S, V, 2, 3): ``vectors[s, i] = intrinsic[s, i] @ frames[s, i]``."""
    @property
    def warped_residual(self) -> Optional[npt.NDArray[np.float64]]:
        """(S, V): ``I⁺ − I⁻`` along the final flow with coarse-to-fine warping, else None."""
    @property
    def vertex_map(self) -> npt.NDArray[np.int64]:
        """(V_input,): the mesh vertex of each input vertex, −1 if dropped."""
    @property
    def energy(self) -> float: ...
    @property
    def energy_at_zero(self) -> float: ...
    @property
    def energy_terms(self) -> Dict[str, float]:
        """``data``, ``speed``, ``spatial``, ``temporal``."""
    @property
    def relative_residual(self) -> float: ...
    @property
    def iterations(self) -> int: ...
    @property
    def reweightings(self) -> int:
        """Reweighted solves of the robust smoothness (0 for the quadratic model)."""
    @property
    def anisotropic_contrasts(self) -> List[float]:
        """Per slab, ``λ`` of the anisotropic smoothness as used (empty without it)."""
    @property
    def robust_scales(self) -> List[float]:
        """Per slab, ``ε`` of the robust smoothness as used (empty without it)."""
    @property
    def solver(self) -> str: ...
    @property
    def solver_reason(self) -> str: ...
    @property
    def preconditioned_spectrum(self) -> tuple[float, float] | None: ...
    @property
    def seconds(self) -> Dict[str, float]:
        """``assembly``, ``factorization``, ``solve``, ``total`` (of all solves)."""
    @property
    def solves(self) -> List[Dict[str, Any]]:
        """Each solve of a run of several: ``label``, ``seconds``, ``iterations``."""
    @property
    def mesh_faces(self) -> npt.NDArray[np.int64]:
        """(F, 3): the triangles over the mesh's (welded) vertices."""
    @property
    def times(self) -> npt.NDArray[np.float64]:
        """(K,): the frame times."""
    @property
    def weights(self) -> Dict[str, float]:
        """``alpha``, ``beta``, ``gamma`` as used, in the data's units."""
    def summary_json(self) -> str:
        """The CLI's summary.json as a string."""
    def write(
        self,
        out: Union[str, PathLike[str]],
        formats: List[str],
        force: bool,
        recording: Optional[Dict[str, Any]] = None,
    ) -> None: ...
    def score_tracks(self, tracks: npt.NDArray[np.float64]) -> Tuple[str, Dict[str, Any]]:
        """Summary JSON and per-point arrays of the flow scored at tracks (K, N, 3)."""
    def analysis(self) -> Dict[str, Any]:
        """The arrays of ``meshflow analyze``, ``faces`` and ``slabs`` (JSON)."""
    def advect(self, seeds: Optional[npt.NDArray[np.float64]]) -> Tuple[Any, ...]:
        """Positions, faces, barycentric, intensity, reached_boundary of the trajectories."""
    def render(
        self,
        out: str,
        slabs: Optional[str],
        size: Tuple[int, int],
        view: Optional[str],
        up: Optional[str],
        flow_scale: Optional[float],
        force: bool,
    ) -> List[str]: ...

def compute_flow(
    positions: npt.NDArray[np.float64],
    faces: npt.NDArray[np.int64],
    intensity: npt.NDArray[np.float64],  # (K, V) or (K, V, C)
    times: Optional[npt.NDArray[np.float64]],
    params: Dict[str, Any],
    mesh: Dict[str, Any],
    progress: Optional[Callable[[Dict[str, Any]], Any]],
) -> Flow: ...
def operators(
    positions: npt.NDArray[np.float64],
    faces: npt.NDArray[np.int64],
    mesh: Dict[str, Any],
) -> Dict[str, Any]: ...
def load_sequence(
    path: str,
    intensity: Optional[str],
    intensity_attribute: Optional[str],
    times: Optional[List[float]],
    fps: Optional[float],
    animation: Optional[str],
    mesh: Dict[str, Any],
) -> Tuple[Any, ...]: ...
def load_mesh_sequence(
    path: str,
    times: Optional[List[float]],
    fps: Optional[float],
    animation: Optional[str],
    mesh: Dict[str, Any],
) -> Tuple[Any, ...]: ...
def python_words(message: str) -> str: ...
def track(
    frames: List[Tuple[Any, Any, Any]],
    times: Optional[List[float]],
    max_step: Optional[float],
    keep_going: bool,
    reference: Optional[Tuple[Any, Any]],
) -> Tuple[Any, ...]: ...
def limits(
    memory_limit: Optional[str],
    allow_external_files: Optional[bool],
) -> Tuple[int, bool]: ...
def match_tracks(
    frames: List[npt.NDArray[np.float64]],
    max_distance: Optional[float],
) -> npt.NDArray[np.float64]: ...
def fit_surface(
    frames: List[npt.NDArray[np.float64]],  # (N_k, 3) each
    shape: str,
    whole_sphere: bool,
    vertices: Optional[int],
    edge_length: Optional[float],
    smoothing: float,
    margin: float,
) -> Dict[str, Any]:
    """``positions`` (K, V, 3), ``faces`` (F, 3), ``reference``, ``frames``,
    ``mean_point_spacing``, ``lambda``."""
def sample_volume(
    volumes: List[npt.NDArray[np.float32]],  # (Z, Y, X) each
    positions: npt.NDArray[np.float64],
    faces: npt.NDArray[np.int64],
    voxel_size: Tuple[float, float, float],
    origin: Tuple[float, float, float],
    smoothing: Optional[float],
    shell: Optional[Tuple[float, float]],
    layers: int,
    reduce: str,
    allow_outside: bool,
) -> Dict[str, Any]:
    """``values`` (K, V), ``outside`` (per frame), ``no_data`` (K, V), ``shell`` (inside, outside, layers),
    ``smoothing``."""
def sample_volume_file(
    path: str,
    positions: npt.NDArray[np.float64],
    faces: npt.NDArray[np.int64],
    voxel_size: Optional[Tuple[float, float, float]],
    origin: Tuple[float, float, float],
    channel: Optional[int],
    resolution_level: int,
    smoothing: Optional[float],
    shell: Optional[Tuple[float, float]],
    layers: int,
    reduce: str,
    allow_outside: bool,
) -> Dict[str, Any]:
    """As ``sample_volume``, the volumes read one frame at a time from ``path``; adds
    ``voxel_size``, ``voxel_size_source``, ``shape`` (z, y, x) and ``origin``."""
def read_volumes(
    path: str,
    voxel_size: Optional[Tuple[float, float, float]],
    origin: Tuple[float, float, float],
    channel: Optional[int],
    resolution_level: int,
    frames: Optional[List[int]],
) -> Dict[str, Any]:
    """``volumes`` (K, Z, Y, X) float32, ``voxel_size``, ``origin``, ``voxel_size_source``."""
def find_surface(
    volume: npt.NDArray[np.float32],  # (Z, Y, X)
    voxel_size: Tuple[float, float, float],
    origin: Tuple[float, float, float],
    level: str,
    smoothing: Optional[float],
) -> Dict[str, Any]:
    """``positions`` (V, 3), ``faces`` (F, 3), the report's numbers and ``warnings``."""
def closed_surface_sequence(
    path: str,
    voxel_size: Optional[Tuple[float, float, float]],
    origin: Tuple[float, float, float],
    channel: Optional[int],
    resolution_level: int,
    level: str,
    smoothing: Optional[float],
    genus: int,
    closing: Optional[float],
    vertices: Optional[int],
    times: Optional[List[float]],
    relax_iterations: int,
    keep_going: bool,
    progress: Optional[Any],
) -> Dict[str, Any]:
    """``positions`` (K, V, 3), ``faces`` (F, 3), ``times``, ``voxel_size``, ``report`` (JSON)."""
def read_run(run: str, arrays: List[str], documents: List[str]) -> Dict[str, Any]:
    """``command``, ``files``, ``surface`` (``positions``, ``faces``, ``intensity``, ``times``,
    ``vertex_map``), ``arrays``, ``documents`` and ``recording`` (or None) of a run."""
def write_sequence(
    out: str,
    positions: npt.NDArray[np.float64],
    faces: npt.NDArray[np.int64],
    values: Optional[npt.NDArray[np.float64]],
    times: List[float],
    vectors: Optional[npt.NDArray[np.float64]],
    force: bool,
) -> None:
    """An NPY sequence with surface_KKKK.vtu and surface.pvd, staged into ``out``."""
