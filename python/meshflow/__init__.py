"""Optical flow on moving surfaces.

Given a triangle mesh that moves and deforms over time (frames ``k = 0..K-1`` at times
``t_k``, one connectivity) and a grey value per vertex and frame, meshflow finds the tangent
vector field ``u`` that moves the image along the surface. It minimizes the energy of Bauer,
Grasmair & Kirisits, "Optical Flow on Moving Manifolds" (SIAM J. Imaging Sci. 8(1), 2015)::

    E(u) = ∫∫ (∂_t I + dI(u))² + β |u|² + γ |∇u|² + (γ/α²) |∇_t u|²  dA dt

with P1 tangent-field finite elements on the mesh, an intrinsic discrete connection and a
polar-decomposition transport in time (``docs/discretization.md`` of the repository).

Functions (NumPy arrays in, NumPy/SciPy out):

- :func:`compute_flow` — the flow of a sequence given as arrays;
- :func:`operators` — the finite-element operators of one mesh as ``scipy.sparse`` matrices;
- :func:`load_sequence` — read a sequence as ``meshflow solve`` reads it (OBJ, PLY, glTF, NPY),
  with or without its image (``image=False``, or :func:`load_mesh_sequence`);
- :func:`write_outputs` — write a flow as the CLI does (NPY, ParaView VTU/PVD, glTF);
- :func:`render` — the PNG pictures of a flow, as ``meshflow render`` draws them;
- :func:`advect` — points (or every vertex) carried along a flow, as ``meshflow advect``;
- :func:`analyze` — divergence, curl, Hodge parts and strain rate of a flow (``meshflow analyze``);
- :func:`track` — turn frames meshed each on its own into one moving mesh;
- :func:`match_tracks`, :func:`score_tracks` — tracks from point clouds (cells, beads), and a
  flow scored at them;
- :func:`fit_surface`, :func:`sample_volume` — a moving surface fitted through point clouds,
  and a microscope recording (3-D volumes) read onto it: the mesh and the image a flow needs;
- :func:`set_limits` — the memory limit that files' declared sizes meet, and whether files
  named inside files may lie outside the naming file's directory.

Keyword names and defaults are the command line's (``meshflow solve --help``). Errors are
``ValueError`` (bad data, broken files, bad parameters) or ``OSError`` and its subclasses
(``FileNotFoundError``, ``PermissionError``) when the operating system refuses a file, with
the command line's one-line message in Python's words (``give intensity='FILE.npy'``, ``add
force=True`` where the command line says ``--intensity FILE.npy``, ``--force``). Long computations release the GIL, report to an optional
``progress`` callable and stop on Ctrl-C (``KeyboardInterrupt``) within one solver iteration.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Sequence as SequenceOf, Tuple, Union

import numpy as np

from . import _meshflow
from ._meshflow import Flow

__all__ = [
    "Flow",
    "Sequence",
    "Trajectories",
    "advect",
    "analyze",
    "compute_flow",
    "closed_surface_sequence",
    "find_surface",
    "fit_surface",
    "load_mesh_sequence",
    "load_sequence",
    "match_tracks",
    "set_limits",
    "operators",
    "read_volumes",
    "render",
    "sample_volume",
    "score_tracks",
    "track",
    "write_outputs",
    "__version__",
]

__version__: str = _meshflow.__version__

#: The default relative welding distance (fraction of frame 0's bounding-box diagonal).
DEFAULT_WELD_TOLERANCE = 1e-9

Progress = Callable[[Dict[str, Any]], Any]


def _floats(
    name: str,
    array: Any,
    ndim: int,
    last: Optional[int] = None,
    expected: Optional[str] = None,
) -> np.ndarray:
    """``array`` as float64 (no copy when it already is), its shape checked (``expected``
    names the shape in the error, default from ``ndim`` and ``last``)."""
    try:
        values = np.asarray(array, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name}: not an array of numbers ({error})") from None
    if values.ndim != ndim or (last is not None and values.shape[-1] != last):
        expected = expected or {
            (3, 3): "(frames, vertices, 3)",
            (2, 3): "(vertices, 3)",
            (2, None): "(frames, vertices)",
            (3, None): "(frames, vertices, channels)",
            (1, None): "(frames,)",
        }[(ndim, last)]
        raise ValueError(f"{name} has shape {values.shape}, expected {expected}")
    return values


def _faces(faces: Any) -> np.ndarray:
    """Faces as int64 (F, 3); any integer dtype, any memory order."""
    array = np.asarray(faces)
    if array.dtype.kind not in "iu":
        raise ValueError(f"faces must be integers, got dtype {array.dtype}")
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"faces has shape {array.shape}, expected (faces, 3)")
    if array.dtype == np.uint64 and array.size and array.max() > np.iinfo(np.int64).max:
        raise ValueError("faces names a vertex index beyond int64")
    return array.astype(np.int64, copy=False)


def _mesh_args(
    weld: bool, weld_tolerance: float, repair: bool, channels: str = "auto"
) -> Dict[str, Any]:
    return {
        "weld": bool(weld),
        "weld_tolerance": float(weld_tolerance),
        "repair": bool(repair),
        "channels": str(channels),
    }


def _optional_float(name: str, value: Any) -> Optional[float]:
    if value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None


def compute_flow(
    positions: Any,
    faces: Any,
    intensity: Any,
    times: Any = None,
    *,
    spread: Optional[float] = None,
    time_scale: Optional[float] = None,
    speed_penalty: Optional[float] = None,
    alpha: Optional[float] = None,
    beta: Optional[float] = None,
    gamma: Optional[float] = None,
    regularizer: str = "covariant",
    dirichlet_mix: Optional[float] = None,
    anisotropic: Union[float, str, None] = None,
    anisotropic_sigma: Optional[float] = None,
    anisotropic_in_time: bool = False,
    robust_smoothness: Union[float, str, None] = None,
    flow_driven: str = "isotropic",
    robust_data: Union[float, str, None] = None,
    median_filter: bool = False,
    local_integration: Optional[float] = None,
    channels: str = "auto",
    channel_weights: Optional[SequenceOf[float]] = None,
    boundary: str = "neumann",
    time_coupling: str = "lumped",
    solver: str = "auto",
    tolerance: float = 1e-8,
    levels: Optional[int] = None,
    warps: Optional[int] = None,
    large_motion: Optional[bool] = None,
    weld: bool = True,
    weld_tolerance: float = DEFAULT_WELD_TOLERANCE,
    repair: bool = False,
    progress: Optional[Progress] = None,
) -> Flow:
    """The optical flow of a moving mesh: one tangent vector per vertex and slab.

    Parameters
    ----------
    positions : (K, V, 3) array of float
        Vertex positions of the ``K ≥ 2`` frames (float32 or float64, any memory order).
    faces : (F, 3) array of int
        Triangles indexing ``positions[k]`` (any integer dtype), the same in every frame,
        e.g. ``trimesh.Trimesh.faces``.
    intensity : (K, V) or (K, V, C) array of float
        Grey value of each vertex in each frame, or ``C`` channels (RGB, stains, …): the
        data term sums ``(∂_t I_c + dI_c(u))²`` over them.
    times : (K,) array of float, optional
        Strictly increasing frame times; default ``0, 1, 2, …``.
    spread, time_scale, speed_penalty : float, optional
        Unit-free weights (defaults 0.5, 1 and 0): ``γ = (spread·h̄·S)²``,
        ``α = √γ / (S·time_scale·Δt̄)``, ``β = speed_penalty·S²`` with ``h̄`` the mean edge
        length, ``Δt̄`` the mean frame spacing and ``S`` the image's gradient scale.
    alpha, beta, gamma : float, optional
        The paper's weights as numbers instead (``alpha=float("inf")``: frame by frame).
    regularizer : {"covariant", "strain", "embedded"}
        What ``γ`` weighs: the paper's ``|∇u|²``; the strain ``|Sym ∇u|²``, which is zero
        on rigid motions of the surface (a texture turning with it is not pulled to rest); or
        Kirisits–Lang–Scherzer's ``|∇^{R³}u|² = |∇u|² + |II(u,·)|²``.
    dirichlet_mix : float, optional
        With ``regularizer="strain"``: add ``dirichlet_mix·|∇u|²`` (default 0).
    anisotropic : float or "auto", optional
        ``λ`` (grey value per length, > 0): image-driven anisotropic smoothness
        ``tr(∇u D ∇uᵀ)`` (Nagel–Enkelmann), smoothing along image edges and less across them
        (``2λ²/(|∇I|² + 2λ²)``); ``"auto"``: per slab, 1.5 × the contrast-weighted median
        of its faces (half the total contrast lies below it).
        Covariant and strain regularizers. Default: isotropic.
    anisotropic_sigma : float, optional
        With ``anisotropic``: the width (a length, ≥ 0) over which the image is smoothed on the
        surface before its edges steer the smoothing. Default: the mean edge length.
    anisotropic_in_time : bool
        With ``anisotropic``: weigh the coupling in time by the space-time tensor's time
        entry, so it weakens where the image changes fast in time (Weickert–Schnörr's
        spatio-temporal tensor without its mixed entries). Measured: within 1 % of without on
        every scene of ``examples/motion_boundaries``; default off.
    robust_smoothness : float or "auto", optional
        ``ε``: the Charbonnier penalty ``2ε(√(r + ε²) − ε)`` of the regularizer's density
        ``r`` (linear growth beyond ``|∇u| = ε``, for flows with jumps), by reweighted solves;
        ``"auto"``: per slab, twice the median ``|∇u|`` of a first quadratic solve.
    flow_driven : {"isotropic", "anisotropic"}
        With ``robust_smoothness``: the penalty of ``|∇u|`` (one weight per face) or of each
        principal direction of ``∇u`` (``tr Ψ(∇uᵀ∇u)``, Weickert–Schnörr's flow-driven
        anisotropic; with ``anisotropic``, image- and flow-driven).
    robust_data : float or "auto", optional
        ``ε``: the Charbonnier data term ``2ε(√(d + ε²) − ε)`` of each face's mean squared
        residual ``d`` (linear growth beyond ``ε``: the smooth TV-L1, for images that break
        brightness constancy here and there), by reweighted solves; ``"auto"``: the residual
        that a flow wrong by a tenth of an edge length per frame leaves at the image's typical
        gradient.
    median_filter : bool
        With warping: linearize each warp around the flow's weighted median over each
        vertex's star (Sun, Roth & Black's median filtering between warps).
    local_integration : float, optional
        The combined local-global data term (Bruhn, Weickert & Schnörr): the motion tensor
        averaged over a Gaussian of this standard deviation (a length on the surface), so that
        the flow at a vertex explains its neighbourhood's brightness change.
    channels : {"auto", "rgb", "luma", "grey"}
        Which channels of a (K, V, C) ``intensity`` to use: all (``auto``), the three colour
        channels (``rgb``), their Rec. 709 luma, or their mean (``grey``).
    channel_weights : sequence of float, optional
        The weight of each channel in the data term (default 1 each).
    boundary : {"neumann", "dirichlet"}
    time_coupling : {"lumped", "consistent"}
    solver : {"auto", "direct", "pcg-slab-gauss-seidel", "pcg-time-multigrid", "pcg-jacobi"}
    tolerance : float
        Relative residual at which the iterative solvers stop.
    levels, warps, large_motion
        Coarse-to-fine warping for motions larger than the image's features
        (``large_motion=True``: 4 levels × 2 warps). Default (``large_motion=None``): one
        linear solve, checked against the images warped by its flow, and warped by itself when
        the motion is too large for the linear model (``Flow.large_motion`` says what the
        check found); ``large_motion=False``: the paper's single linear solve, always.
    weld, weld_tolerance, repair
        How the mesh is built from ``faces`` (as the CLI's ``--no-weld``,
        ``--weld-tolerance``, ``--repair``). Results are in the input's vertex numbering
        whatever welding merged (dropped vertices get NaN).
    progress : callable, optional
        Called with a dict per solver event: ``{"kind": "iteration", "iteration": n,
        "relative_residual": r}``, ``{"kind": "factorizing", "slabs": n}`` or ``{"kind":
        "warp", "level": l, "warp": w, "solve": i, "solves": n}`` or ``{"kind":
        "large_motion", "linearization_error": e, "threshold": t}``. An exception it raises
        stops the solve and propagates.

    Returns
    -------
    Flow
        ``vectors`` (S, V, 3), ``intrinsic`` (S, V, 2), ``frames`` (S, V, 2, 3), ``energy``,
        ``energy_terms``, ``relative_residual``, ``iterations``, ``solver``, ``seconds``,
        ``weights`` … with ``S = K − 1`` slabs.
    """
    positions = _floats("positions", positions, 3, 3)
    faces = _faces(faces)
    intensity = _floats("intensity", intensity, 3 if np.ndim(intensity) == 3 else 2)
    if intensity.shape[:2] != positions.shape[:2] or 0 in intensity.shape[2:]:
        raise ValueError(
            f"intensity has shape {intensity.shape}, expected {positions.shape[:2]} "
            "(frames, vertices) or (frames, vertices, channels) to match positions"
        )
    if times is not None:
        times = _floats("times", times, 1)
        if times.shape[0] != positions.shape[0]:
            raise ValueError(f"{times.shape[0]} times for {positions.shape[0]} frames")
    if progress is not None and not callable(progress):
        raise ValueError(f"progress must be callable, got {type(progress).__name__}")
    params = {
        "spread": _optional_float("spread", spread),
        "time_scale": _optional_float("time_scale", time_scale),
        "speed_penalty": _optional_float("speed_penalty", speed_penalty),
        "alpha": _optional_float("alpha", alpha),
        "beta": _optional_float("beta", beta),
        "gamma": _optional_float("gamma", gamma),
        "regularizer": str(regularizer),
        "dirichlet_mix": _optional_float("dirichlet_mix", dirichlet_mix),
        "anisotropic": _scale("anisotropic", anisotropic),
        "anisotropic_sigma": _optional_float("anisotropic_sigma", anisotropic_sigma),
        "anisotropic_in_time": bool(anisotropic_in_time),
        "robust_smoothness": _scale("robust_smoothness", robust_smoothness),
        "flow_driven": str(flow_driven),
        "robust_data": _scale("robust_data", robust_data),
        "median_filter": bool(median_filter),
        "local_integration": None if local_integration is None else float(local_integration),
        "channel_weights": _channel_weights(channel_weights),
        "boundary": str(boundary),
        "time_coupling": str(time_coupling),
        "solver": str(solver),
        "tolerance": float(tolerance),
        "levels": None if levels is None else int(levels),
        "warps": None if warps is None else int(warps),
        "large_motion": None if large_motion is None else bool(large_motion),
    }
    return _meshflow.compute_flow(
        positions,
        faces,
        intensity,
        times,
        params,
        _mesh_args(weld, weld_tolerance, repair, channels),
        progress,
    )


def _scale(name: str, value: Any) -> Optional[str]:
    """A scale for the library: ``"auto"`` or a number, as text."""
    if value is None or value == "auto":
        return value
    try:
        return repr(float(value))
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or 'auto', got {value!r}") from None


def _channel_weights(weights: Any) -> Optional[List[float]]:
    if weights is None:
        return None
    try:
        return [float(w) for w in weights]
    except (TypeError, ValueError):
        raise ValueError(f"channel_weights must be numbers, got {weights!r}") from None


def operators(
    positions: Any,
    faces: Any,
    *,
    weld: bool = True,
    weld_tolerance: float = DEFAULT_WELD_TOLERANCE,
    repair: bool = False,
) -> Dict[str, Any]:
    """The finite-element operators of a mesh, as ``meshflow operators`` writes them.

    Returns a dict with ``scipy.sparse.csc_matrix`` values

    - ``cotan`` (V×V): the cotan Laplacian ``L``, positive semi-definite, ``uᵀLu = ∫|∇u|²``;
    - ``mass_scalar`` (V×V): the consistent P1 mass ``m``;
    - ``stiffness`` (2V×2V): the connection (Bochner) Laplacian ``K``, ``uᵀKu = ∫|∇u|²`` for
      tangent fields with DOFs ``(2i, 2i+1)`` in vertex ``i``'s frame;
    - ``mass`` (2V×2V): the vector mass ``M``, ``uᵀMu = ∫|u|²``;

    and arrays ``frames`` (V, 2, 3), the orthonormal vertex frames in R³ (a tangent field
    ``u`` (V, 2) is ``np.einsum("ik,ikj->ij", u, frames)`` in R³), and ``vertex_map``
    (V_input,), the mesh vertex of each input vertex (−1 if dropped). Matrices are over the
    mesh's vertices (welded, unused ones dropped; the identity for a clean mesh).
    """
    import scipy.sparse

    positions = _floats("positions", positions, 2, 3)
    parts = _meshflow.operators(positions, _faces(faces), _mesh_args(weld, weld_tolerance, repair))
    out: Dict[str, Any] = {}
    for name, value in parts.items():
        if isinstance(value, tuple):
            data, indices, indptr, shape = value
            out[name] = scipy.sparse.csc_matrix((data, indices, indptr), shape=shape)
        else:
            out[name] = value
    return out


@dataclass
class Sequence:
    """A moving mesh with its image, as :func:`load_sequence` or :func:`track` return it.

    ``positions`` (K, V, 3), ``faces`` (F, 3) int64, ``intensity`` (K, V) grey values or
    (K, V, C) channels (colours), or ``None`` when read without an image, ``times`` (K,).
    ``vertex_map`` (V_file,) int64 is the mesh vertex of each vertex of the files (−1 if
    dropped), ``warnings`` what the loader noticed, ``source`` what was read, ``report``
    tracking's per-frame report (``None`` when not tracked).
    """

    positions: np.ndarray
    faces: np.ndarray
    intensity: Optional[np.ndarray]
    times: np.ndarray
    vertex_map: Optional[np.ndarray] = None
    warnings: List[str] = field(default_factory=list)
    source: str = ""
    report: Optional[Dict[str, Any]] = None

    def compute_flow(self, **options: Any) -> Flow:
        """:func:`compute_flow` of this sequence (keywords as there)."""
        if self.intensity is None:
            raise ValueError(
                "this sequence was read without an image (image=False): set its intensity "
                "(K, V) first, e.g. sequence.intensity = values"
            )
        return compute_flow(self.positions, self.faces, self.intensity, self.times, **options)


def load_sequence(
    path: Union[str, PathLike],
    *,
    intensity: Optional[Union[str, PathLike]] = None,
    intensity_attribute: Optional[str] = None,
    times: Optional[SequenceOf[float]] = None,
    fps: Optional[float] = None,
    animation: Optional[Union[str, int]] = None,
    channels: str = "auto",
    weld: bool = True,
    weld_tolerance: float = DEFAULT_WELD_TOLERANCE,
    repair: bool = False,
    image: bool = True,
) -> Sequence:
    """Reads a sequence as ``meshflow solve PATH`` does.

    ``path`` is a directory of .obj/.ply/.gltf/.glb frames, a glob (``"dir/frame_*.ply"``),
    one .gltf/.glb animation (morph targets, skin), or a directory with positions.npy,
    faces.npy and intensity.npy. The image comes from vertex colours, textures, a PLY property
    (``intensity_attribute``) or ``intensity`` (a (K, V_file) or (K, V_file, C) .npy), its
    channels chosen by ``channels`` as the CLI's ``--channels`` (``auto``: RGB for colours,
    one channel for grey colours and values); times from ``times``,
    the animation (resampled at ``fps``), a times.txt beside the frames, or 0, 1, 2, ….
    The arrays are the mesh's (welded); ``vertex_map`` relates them to the files' vertices.
    With ``image=False`` only the surfaces are read (:func:`load_mesh_sequence`): files
    without colours are fine, and ``intensity`` is ``None`` until you set it.
    """
    if not image:
        if intensity is not None or intensity_attribute is not None:
            raise ValueError("image=False reads no image: drop intensity and intensity_attribute")
        return load_mesh_sequence(
            path,
            times=times,
            fps=fps,
            animation=animation,
            weld=weld,
            weld_tolerance=weld_tolerance,
            repair=repair,
        )
    loaded = _meshflow.load_sequence(
        _path(path),
        None if intensity is None else _path(intensity),
        intensity_attribute,
        None if times is None else [float(t) for t in times],
        _optional_float("fps", fps),
        None if animation is None else str(animation),
        _mesh_args(weld, weld_tolerance, repair, channels),
    )
    positions, faces, grey, frame_times, vertex_map, warnings, source = loaded
    return Sequence(positions, faces, grey, frame_times, vertex_map, warnings, source)


def load_mesh_sequence(
    path: Union[str, PathLike],
    *,
    times: Optional[SequenceOf[float]] = None,
    fps: Optional[float] = None,
    animation: Optional[Union[str, int]] = None,
    weld: bool = True,
    weld_tolerance: float = DEFAULT_WELD_TOLERANCE,
    repair: bool = False,
) -> Sequence:
    """The surfaces of a sequence as :func:`load_sequence` reads them, without an image: for
    values you bring yourself (a simulation, a measurement, :func:`sample_volume`). The
    :class:`Sequence` has ``intensity=None``; set it to a (K, V) array of the mesh's vertices
    before :meth:`Sequence.compute_flow`."""
    loaded = _meshflow.load_mesh_sequence(
        _path(path),
        None if times is None else [float(t) for t in times],
        _optional_float("fps", fps),
        None if animation is None else str(animation),
        _mesh_args(weld, weld_tolerance, repair, "auto"),
    )
    positions, faces, frame_times, vertex_map, warnings, source = loaded
    if frame_times is None:
        frame_times = np.arange(positions.shape[0], dtype=np.float64)
    return Sequence(
        positions, faces, None, np.asarray(frame_times, dtype=np.float64), vertex_map, warnings,
        source,
    )


@dataclass
class Trajectories:
    """Points carried along a flow (:func:`advect`): ``positions`` (K, N, 3) on each frame,
    ``faces`` (K, N) int64 and ``barycentric`` (K, N, 3) (where they are as mesh points),
    ``intensity`` (K, N) (the image they see: for vertex seeds the sequence reparametrized by
    the flow, nearly static for a good flow), ``reached_boundary`` (N,) bool, and for vertex
    seeds ``sequence``, the mesh riding on the flow."""

    positions: np.ndarray
    faces: np.ndarray
    barycentric: np.ndarray
    intensity: np.ndarray
    reached_boundary: np.ndarray
    sequence: Optional[Sequence] = None


def advect(flow: Flow, seeds: Any = None) -> Trajectories:
    """Follows points through the frames along ``flow`` (``meshflow advect``): each slab's flow
    moves them along straightest geodesics of the surface, in 4 substeps.

    ``seeds`` (N, 3) are taken to their closest points of frame 0's surface; by default every
    mesh vertex is followed, and then ``sequence`` is the mesh moved by the flow (positions,
    the flow's faces, the image the vertices see, the times): a :class:`Sequence` to solve,
    write or compare.
    """
    points = None if seeds is None else _floats("seeds", seeds, 2, 3, "(points, 3)")
    positions, faces, barycentric, grey, boundary = flow.advect(points)
    result = Trajectories(positions, faces, barycentric, grey, boundary)
    if seeds is None:
        result.sequence = Sequence(
            positions, flow.mesh_faces, grey, flow.times, source="advected"
        )
    return result


def analyze(flow: Flow) -> Dict[str, Any]:
    """What the flow tells, per slab on the slab's mean geometry (``meshflow analyze``).

    Vertex arrays (S, V) in the input's numbering: ``divergence``, ``curl`` (weak form),
    ``potential`` (φ) and ``stream`` (ψ, the mean of its edges' values); face arrays (S, F)
    over ``faces`` (F, 3): ``face_divergence``, ``face_curl``, ``areal_rate`` (tr D =
    d/dt log area), ``shear_rate`` (|dev D|), ``principal_rates`` (S, F, 2); R³ vectors on
    frame ``s`` (S, F, 3): ``stretch_direction``, ``hodge_exact`` (∇φ), ``hodge_coexact``
    (J∇ψ), ``hodge_harmonic``; and ``slabs``, per slab its ``time``, ``area``, ``mean_speed``,
    ``mean_divergence``, ``mean_curl``, ``mean_areal_rate``, ``mean_shear_rate`` and the
    energies ``energy``, ``exact_energy``, ``coexact_energy``, ``harmonic_energy``. Rates are
    in 1/time. The formulas are in ``docs/guide.md`` ("What the flow tells").
    """
    result = flow.analysis()
    result["slabs"] = json.loads(result["slabs"])
    return result


def render(
    flow: Flow,
    out: Union[str, PathLike],
    *,
    slabs: Optional[Union[str, SequenceOf[int]]] = None,
    size: Tuple[int, int] = (960, 720),
    view: Optional[Tuple[float, ...]] = None,
    up: Optional[str] = None,
    flow_scale: Optional[float] = None,
    force: bool = False,
) -> List[str]:
    """Draws the pictures of ``meshflow render`` into the new directory ``out`` and returns
    their paths: per slab ``grey_SSSS.png``, ``flow_SSSS.png`` (colour wheel),
    ``arrows_SSSS.png`` (and ``residual_SSSS.png`` after warping), all slabs from one camera
    with one flow scale. ``slabs``: a list of slab numbers or ``"0,5,10-20,last"`` (default
    all); ``view`` (azimuth, elevation[, roll]) in degrees; ``up`` ``"x"``, ``"y"``, ``"z"``
    (or negated); ``flow_scale`` the speed at the wheel's rim (default: the 99th percentile).
    ``out`` is replaced if it is an earlier meshflow output; any other non-empty directory is
    refused unless ``force``."""
    if slabs is not None and not isinstance(slabs, str):
        slabs = ",".join(str(_count("slabs", s)) for s in slabs)
    width, height = (int(x) for x in size)
    angles = None
    if view is not None:
        if len(view) not in (2, 3):
            raise ValueError(f"view must be (azimuth, elevation[, roll]) in degrees, got {view!r}")
        angles = ",".join(str(float(a)) for a in view)
    written = flow.render(
        _path(out), slabs, (width, height), angles, up,
        _optional_float("flow_scale", flow_scale), bool(force),
    )
    return [_path(p) for p in written]


def write_outputs(
    flow: Flow,
    out: Union[str, PathLike],
    *,
    formats: SequenceOf[str] = ("npy", "vtu", "glb"),
    force: bool = False,
    recording: Optional[Dict[str, Any]] = None,
) -> None:
    """Writes ``flow`` as ``meshflow solve --out OUT`` does: flow.npy, flow_intrinsic.npy,
    flow_SSSS.vtu + flow.pvd (ParaView), flow.glb and summary.json, staged and renamed into
    place whole. A directory holding files meshflow did not write is refused unless
    ``force``; an earlier meshflow output there is replaced. The run also holds the sequence
    (positions.npy, faces.npy, intensity.npy, times.txt), so ``meshflow advect OUT`` and
    ``meshflow render OUT`` work on it as on a run of the command line.

    ``recording`` names the microscope recording the image was sampled from, as ``meshflow
    sample`` names it in the sequence's manifest, so that viewers (``meshflow.napari``) show
    the surface over it: a dict with ``path``, ``shape`` (its frames' (Z, Y, X)),
    ``voxel_size`` and ``origin`` (x, y, z), ``channel`` (or None) and ``resolution_level``."""
    if isinstance(formats, str):
        formats = [formats]
    if recording is not None:
        recording = {
            "path": _path(recording["path"]),
            "shape": [int(n) for n in recording["shape"]],
            "voxel_size": list(_triple("voxel_size", recording["voxel_size"])),
            "origin": list(_triple("origin", recording.get("origin", (0.0, 0.0, 0.0)))),
            "channel": None if recording.get("channel") is None else int(recording["channel"]),
            "resolution_level": int(recording.get("resolution_level", 0)),
        }
    flow.write(_path(out), [str(f) for f in formats], bool(force), recording)


def track(
    frames: SequenceOf[Tuple[Any, ...]],
    times: Optional[SequenceOf[float]] = None,
    *,
    max_step: Optional[float] = None,
    keep_going: bool = False,
    reference: Optional[Tuple[Any, Any]] = None,
    reference_vertices: Optional[int] = None,
    relax: str = "arap",
    relax_iterations: int = 20,
    align: str = "none",
    keep_uncovered: bool = False,
) -> Sequence:
    """One moving mesh from frames meshed each on its own (``meshflow track``).

    ``frames`` is a list of ``(positions (V_k, 3), faces (F_k, 3), intensity (V_k,) or
    None)``. From frame to frame every vertex of the reference mesh (``reference =
    (positions, faces)``, default frame 0's; ``reference_vertices=N`` simplifies it to about
    N vertices) moves along its normal to the next frame's surface, is relaxed there as
    rigidly as possible against the previous frame (``relax="arap"``, up to
    ``relax_iterations`` steps; ``"none"``: normal motion only) and takes that frame's grey
    value. ``align`` (``"none"``, ``"rigid"``, ``"similarity"``) takes the sample's drift out
    between frames. Reference vertices beyond a frame's boundary are trimmed away unless
    ``keep_uncovered``. ``max_step`` bounds a step (default 10 % of frame 0's bounding-box
    diagonal); ``keep_going`` counts vertices beyond it and flipped triangles instead of
    failing. Returns the :class:`Sequence`, with the per-frame ``report``.
    """
    if relax not in ("arap", "none"):
        raise ValueError(f"relax must be 'arap' or 'none', got {relax!r}")
    if align not in ("none", "rigid", "similarity"):
        raise ValueError(f"align must be 'none', 'rigid' or 'similarity', got {align!r}")
    if reference_vertices is not None and int(reference_vertices) < 4:
        raise ValueError(f"reference_vertices must be at least 4, got {reference_vertices}")
    converted = []
    for k, frame in enumerate(frames):
        if len(frame) not in (2, 3):
            raise ValueError(f"frames[{k}]: expected (positions, faces[, intensity])")
        positions = _floats(f"frames[{k}] positions", frame[0], 2, 3)
        grey = None
        if len(frame) == 3 and frame[2] is not None:
            grey = _floats(f"frames[{k}] intensity", frame[2], 1)
            if grey.shape[0] != positions.shape[0]:
                raise ValueError(
                    f"frames[{k}]: {grey.shape[0]} grey values for {positions.shape[0]} vertices"
                )
        converted.append((positions, _faces(frame[1]), grey))
    if reference is not None:
        reference = (_floats("reference positions", reference[0], 2, 3), _faces(reference[1]))
    result = _meshflow.track(
        converted,
        None if times is None else [float(t) for t in times],
        _optional_float("max_step", max_step),
        bool(keep_going),
        reference,
        None if reference_vertices is None else int(reference_vertices),
        0 if relax == "none" else int(relax_iterations),
        align,
        bool(keep_uncovered),
    )
    positions, faces, grey, frame_times, report = result
    return Sequence(positions, faces, grey, frame_times, source="tracked", report=json.loads(report))


def _path(path: Union[str, PathLike]) -> str:
    import os

    return os.fspath(path)


def set_limits(
    *,
    memory_limit: Union[int, str, None] = None,
    allow_external_files: Optional[bool] = None,
) -> Dict[str, Any]:
    """The process's guards against hostile files, as ``--memory-limit`` and
    ``--allow-external-files`` set them on the command line; returns both as they are then.

    ``memory_limit``: bytes (an int) or a size such as ``"1.5G"``, ``"800M"``; ``"default"``
    for the machine's physical memory. Sizes that files declare (NPY shapes, TIFF pages, PLY
    counts, glTF buffers, images) are checked against it before anything is allocated, and
    the solver's factors take at most 35 % of it. ``allow_external_files``: read files that
    files name (glTF buffers and images, OBJ material libraries and textures) also outside the
    naming file's directory (trusted data only). The settings hold for the whole process.
    """
    size = None if memory_limit is None else str(memory_limit)
    limit, external = _meshflow.limits(size, allow_external_files)
    return {"memory_limit": limit, "allow_external_files": external}


def match_tracks(
    frames: SequenceOf[Any], *, max_distance: Optional[float] = None
) -> np.ndarray:
    """Point clouds per frame (a list of (N_k, 3) arrays: cell centres, beads, landmarks)
    chained into tracks by mutual nearest neighbours between consecutive frames, within
    ``max_distance`` (default: half the median nearest-neighbour distance in frame 0).

    Returns (K, N, 3) float64 positions, NaN where a track has no point: what
    :func:`score_tracks` and ``meshflow solve --ground-truth-tracks`` take.
    """
    points = [_floats(f"frames[{k}]", f, 2, 3) for k, f in enumerate(frames)]
    return _meshflow.match_tracks(points, _optional_float("max_distance", max_distance))


def score_tracks(flow: Flow, tracks: Any) -> Dict[str, Any]:
    """The flow scored where the motion is known at some points only.

    ``tracks`` (K, N, 3): positions per frame, NaN where a point is not tracked. Per slab and
    overall, against the zero flow: the endpoint error of the tangential displacement relative
    to the mesh at each point's closest surface point (``mean_endpoint``,
    ``median_endpoint``, ``zero_mean_endpoint``, ``endpoint_ratio``, …), the direction error
    for points that moved and the median speed ratio, as summary.json's
    ``ground_truth_tracks`` (``slabs`` per slab; ``points`` counts the scored points), and
    ``per_point``: arrays ``slab``,
    ``track``, ``position`` (on the surface), ``truth`` and ``computed`` (displacements over
    the slab), ``endpoint``, ``direction_degrees`` (NaN where the point did not move),
    ``distance`` (from the surface).
    """
    summary, points = flow.score_tracks(_floats("tracks", tracks, 3, 3))
    scores = json.loads(summary)
    scores["per_point"] = points
    return scores


def _point_frames(points: Any) -> List[np.ndarray]:
    """Points per frame as float64 (N_k, 3) arrays: from a list of (N_k, 3) arrays, one
    (K, N, 3) array (all-NaN rows, untracked points, dropped) or one (N, 3) array (one
    frame)."""
    if isinstance(points, np.ndarray):
        if points.ndim == 3:
            tracks = _floats("points", points, 3, 3, "(frames, points, 3)")
            return [frame[~np.isnan(frame).all(axis=1)] for frame in tracks]
        return [_floats("points", points, 2, 3, "(frames, points, 3) or (points, 3)")]
    if isinstance(points, (str, bytes)) or not hasattr(points, "__len__"):
        raise ValueError(
            f"points must be a list of (points, 3) arrays or a (frames, points, 3) array, "
            f"got {type(points).__name__}"
        )
    return [_floats(f"points[{k}]", f, 2, 3, "(points, 3)") for k, f in enumerate(points)]


def _count(name: str, value: Any) -> Optional[int]:
    """A count ≥ 0 (the library names 0 where it is wrong), or None."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ValueError(f"{name} must be a whole number ≥ 0, got {value!r}")
    return int(value)


def fit_surface(
    points: Any,
    shape: str = "sphere-like",
    *,
    whole_sphere: bool = False,
    vertices: Optional[int] = None,
    edge_length: Optional[float] = None,
    smoothing: float = 1.0,
    margin: float = 1.0,
) -> Dict[str, Any]:
    """A moving surface fitted through point clouds (``meshflow surface``): one mesh with fixed
    faces whose vertices move with the points, frame by frame.

    A reference surface is chosen once for all frames, and each frame's surface is a height
    along its normal, a thin-plate smoothing spline through that frame's points:

    - ``shape="sphere-like"``: over a sphere fitted to frame 0's points (cell centres of an
      embryo, an organoid, a yolk), meshed as an icosphere cut to the cap their directions
      cover plus ``margin``, or the whole sphere with ``whole_sphere=True``;
    - ``shape="graph"``: a height ``z = h(x, y)`` over the points' ``(x, y)`` bounding box
      plus ``margin`` (a sheet of tissue seen from above).

    Parameters
    ----------
    points : list of (N_k, 3) arrays, or a (K, N, 3) array
        The points of each frame (the counts may differ). In a (K, N, 3) array, as
        :func:`match_tracks` returns, all-NaN rows (untracked) are dropped, as the CLI's
        ``meshflow surface`` drops them; elsewhere a point that
        is not finite is an error. One (N, 3) array is one frame.
    shape : {"sphere-like", "graph"}
    whole_sphere : bool
        With ``"sphere-like"``: mesh the whole sphere, not just the cap the points cover.
    vertices : int, optional
        About this many mesh vertices (default 16,000).
    edge_length : float, optional
        The mesh's mean edge length at most this, in the points' units, instead of
        ``vertices`` (giving both is a ``ValueError``).
    smoothing : float
        The smoothing length in mean point spacings: height variations shorter than it are
        smoothed away (0: as close to the points as the mesh allows). Unit-free: scaling the
        points scales the surface and nothing else.
    margin : float
        How far the mesh reaches beyond the outermost point, in mean point spacings.

    Returns
    -------
    dict
        ``positions`` (K, V, 3) float64 and ``faces`` (F, 3) int64 (counter-clockwise seen
        from outside: normals away from the sphere's centre, or +z), what
        :func:`compute_flow` and :func:`sample_volume` take; ``reference``: ``{"kind":
        "sphere", "centre", "radius", "cap_degrees" (None for the whole sphere), "axis"}`` or
        ``{"kind": "plane", "min", "max"}`` (the rectangle of ``z = 0``, ``(x, y)`` corners);
        ``frames``: per frame ``{"points", "dropped" (outside the reference mesh),
        "rms_residual", "max_residual"}`` (distances of the points from the surface along its
        normal); ``mean_point_spacing`` ``d̄`` (the unit of ``smoothing`` and ``margin``);
        ``lambda``, the spline's weight ``smoothing⁴ · d̄²``.

    Errors (``ValueError``, naming the frame and point): fewer than 3 points in a frame
    (4 in frame 0 of a sphere), points that are not finite, frame 0's points on a plane
    (``"sphere-like"``) or their ``(x, y)`` on a line (``"graph"``).

    Example: a surface through cell centres, a recording read onto it, its flow::

        surface = meshflow.fit_surface(cells, vertices=5000)        # cells: list of (N_k, 3)
        grey = meshflow.sample_volume(stack, surface["positions"], surface["faces"],
                                      voxel_size=(0.4, 0.4, 2.0))["values"]
        flow = meshflow.compute_flow(surface["positions"], surface["faces"], grey)
    """
    frames = _point_frames(points)
    if not isinstance(shape, str):
        raise ValueError(f"shape must be \"sphere-like\" or \"graph\", got {shape!r}")
    smoothing_value = _optional_float("smoothing", smoothing)
    margin_value = _optional_float("margin", margin)
    if smoothing_value is None or margin_value is None:
        raise ValueError("smoothing and margin must be numbers, not None")
    return _meshflow.fit_surface(
        frames,
        shape,
        bool(whole_sphere),
        _count("vertices", vertices),
        _optional_float("edge_length", edge_length),
        smoothing_value,
        margin_value,
    )


def _volume_frames(volumes: Any) -> List[np.ndarray]:
    """Volumes as float32 (Z, Y, X) arrays: from a (K, Z, Y, X) array or a list of (Z, Y, X)
    arrays of floats or integers."""

    def as_float32(name: str, array: Any, ndim: int, expected: str) -> np.ndarray:
        values = np.asarray(array)
        if values.dtype.kind not in "fiu":
            raise ValueError(f"{name} must be numbers (float or integer), got dtype {values.dtype}")
        if values.ndim != ndim:
            raise ValueError(f"{name} has shape {values.shape}, expected {expected}")
        return values.astype(np.float32, copy=False)

    if isinstance(volumes, np.ndarray):
        return list(as_float32("volumes", volumes, 4, "(frames, z, y, x), or a list of (z, y, x)"))
    if isinstance(volumes, (str, bytes)) or not hasattr(volumes, "__len__"):
        raise ValueError(
            f"volumes must be a (frames, z, y, x) array or a list of (z, y, x) arrays, "
            f"got {type(volumes).__name__}"
        )
    return [as_float32(f"volumes[{k}]", v, 3, "(z, y, x)") for k, v in enumerate(volumes)]


def _is_path(value: Any) -> bool:
    return isinstance(value, (str, PathLike))


def _optional_triple(name: str, value: Any) -> Optional[Tuple[float, float, float]]:
    return None if value is None else _triple(name, value)


def _level(name: str, value: Any) -> int:
    count = _count(name, value)
    if count is None:
        raise ValueError(f"{name} must be a whole number ≥ 0, not None")
    return count


def read_volumes(
    path: Union[str, PathLike],
    *,
    voxel_size: Optional[SequenceOf[float]] = None,
    origin: SequenceOf[float] = (0.0, 0.0, 0.0),
    channel: Optional[int] = None,
    resolution_level: int = 0,
    frames: Optional[SequenceOf[int]] = None,
) -> Dict[str, Any]:
    """A recording's volumes read as ``meshflow sample`` and ``meshflow surface`` read them:
    an ``.npy`` of (Z, Y, X) or (K, Z, Y, X), a TIFF stack or an ImageJ hyperstack (Fiji's
    and tifffile's 4-D/5-D TIFF), an OME-Zarr image (NGFF 0.4 or 0.5), or a directory of
    ``.npy``/``.tif`` files, one frame each.

    Parameters
    ----------
    path : str or PathLike
        The recording.
    voxel_size : (d_x, d_y, d_z), optional
        Default: from the files' metadata (ImageJ's, or OME-Zarr's ``scale``), else 1 × 1 × 1.
    origin : (x, y, z)
        The position of voxel ``(0, 0, 0)``'s centre (an OME-Zarr image's own translation is
        added).
    channel : int, optional
        OME-Zarr images and hyperstacks: the channel (default 0).
    resolution_level : int
        OME-Zarr: the pyramid level (0: the finest).
    frames : list of int, optional
        Only these frames, in this order; the others are not read. Default: every frame.

    Returns
    -------
    dict
        ``volumes`` (K, Z, Y, X) float32, ``voxel_size`` and ``origin`` as placed, and
        ``voxel_size_source`` (where the voxel size came from; None where given).

    What is held is checked against the memory limit (:func:`set_limits`) before anything is
    read; a recording larger than memory goes to :func:`sample_volume` as a path instead,
    which reads one frame at a time.
    """
    if frames is not None:
        frames = [_level("frames[]", k) for k in frames]
    return _meshflow.read_volumes(
        _path(path),
        _optional_triple("voxel_size", voxel_size),
        _triple("origin", origin),
        _count("channel", channel),
        _level("resolution_level", resolution_level),
        frames,
    )


def find_surface(
    volume: Any,
    voxel_size: Optional[SequenceOf[float]] = None,
    *,
    origin: SequenceOf[float] = (0.0, 0.0, 0.0),
    level: Union[str, float] = "auto",
    smoothing: Optional[float] = None,
    genus: int = 0,
    closing: Optional[float] = None,
    frame: int = 0,
    channel: Optional[int] = None,
    resolution_level: int = 0,
) -> Dict[str, Any]:
    """The surface of the object in one 3-D image, as ``meshflow surface --shape closed`` finds
    it in each frame: Gaussian smoothing, a threshold (Otsu's, or ``level``), the foreground
    closed by the smallest ball that leaves one object of at most ``genus`` handles (the gaps of
    a patchy layer, or between nuclei, sealed), its largest 6-connected piece with its holes
    filled, its isosurface by surface nets cleaned to one closed manifold, and, where the
    object is a bright layer around a darker inside, each vertex moved to the middle of the
    layer.

    Parameters
    ----------
    volume : (Z, Y, X) array of float or integer, or a path
        The image in NumPy's ``(z, y, x)`` order, or a recording on disk (as
        :func:`read_volumes` reads it), of which frame ``frame`` is read.
    voxel_size : (d_x, d_y, d_z), optional
        The voxel's sides in physical units, ``(x, y, z)`` order. Default: 1 × 1 × 1 for an
        array, the files' metadata for a path.
    origin : (x, y, z)
        The position of voxel ``(0, 0, 0)``'s centre.
    frame, channel, resolution_level : int
        For a path: which frame, channel and pyramid level (:func:`read_volumes`).
    level : "auto" or float
        The threshold of the smoothed image; "auto" is Otsu's (a probability map works at 0.5).
    smoothing : float, optional
        ``σ`` of the Gaussian, physical units; default the largest voxel side.
    genus : int
        The handles the object has: 0 (a sphere's topology) unless it really has some.
    closing : float, optional
        The radius of the ball that first closes the gaps of the object's layer (physical
        units; 0: none). Default: none; where the genus is wrong or the object thin it grows
        from the largest voxel side by half each time until the surface has at most ``genus``
        handles, then (genus 0) the same with every slice's holes filled too.

    Returns
    -------
    dict
        ``positions`` (V, 3) and ``faces`` (F, 3) of the surface (its own vertices: track
        several frames' surfaces into one mesh with :func:`track`), and ``threshold``,
        ``foreground_voxels``, ``component_voxels``, ``component_share``, ``filled_voxels``,
        ``genus``, ``closing_radius`` (0 where no gap needed sealing), ``slices_filled``,
        ``smoothing`` (the σ used: doubled for a porous foreground), ``layer_vertices``,
        ``layer_thickness``, ``border_voxels`` as ``surface.json`` has them, and ``warnings``
        (the object touching the border, or split).

    Errors are ``ValueError`` with the library's message: a constant image, no voxel above
    ``level`` or every voxel above it, an object too small to bound, a surface that keeps more
    handles than ``genus``.
    """
    if _is_path(volume):
        read = read_volumes(
            volume,
            voxel_size=voxel_size,
            origin=origin,
            channel=channel,
            resolution_level=resolution_level,
            frames=[frame],
        )
        image, voxel_size, origin = read["volumes"][0], read["voxel_size"], read["origin"]
    else:
        if channel is not None or resolution_level != 0 or frame != 0:
            raise ValueError("frame, channel and resolution_level apply to a path, not an array")
        image = _volume_frames([volume])[0]
    text = _level_text(level)
    return _meshflow.find_surface(
        image,
        _triple("voxel_size", (1.0, 1.0, 1.0) if voxel_size is None else voxel_size),
        _triple("origin", origin),
        text,
        _optional_float("smoothing", smoothing),
        _count("genus", genus),
        _optional_float("closing", closing),
    )


def closed_surface_sequence(
    path: Union[str, PathLike],
    voxel_size: Optional[SequenceOf[float]] = None,
    *,
    origin: SequenceOf[float] = (0.0, 0.0, 0.0),
    channel: Optional[int] = None,
    resolution_level: int = 0,
    level: Union[str, float] = "auto",
    smoothing: Optional[float] = None,
    genus: int = 0,
    closing: Optional[float] = None,
    vertices: Optional[int] = None,
    times: Optional[SequenceOf[float]] = None,
    relax_iterations: int = 20,
    keep_going: bool = False,
    progress: Optional[Progress] = None,
) -> Sequence:
    """The object's surface in every frame of the recording at ``path``, tracked into one
    moving mesh: what ``meshflow surface PATH --shape closed`` writes, computed by the same
    library function, frame by frame (one volume held at a time).

    Each frame's surface is found as :func:`find_surface` finds it (``level``, ``smoothing``,
    ``genus``, ``closing``; each frame's closing and smoothing start where earlier frames
    needed them), and a reference of about ``vertices`` vertices (default 16,000, or fewer
    where its edges would be shorter than the smoothing) follows them, rigidly aligned and
    relaxed (``relax_iterations``; 0: none). A tracked mesh that folds at more than 0.1 % of
    its edges in a frame is a ``ValueError`` unless ``keep_going``. ``progress`` is called with
    ``{"kind": "surface", "frame": k, "frames": K}`` as each frame's surface is found.

    Returns a :class:`Sequence` without an image (``intensity`` None; :func:`sample_volume`
    gives it), with ``report`` (``surface.json``'s) and the voxel size used in
    ``report["voxel_size"]``.
    """
    text = _level_text(level)
    found = _meshflow.closed_surface_sequence(
        _path(path),
        None if voxel_size is None else _triple("voxel_size", voxel_size),
        _triple("origin", origin),
        None if channel is None else _count("channel", channel),
        _level("resolution_level", resolution_level),
        text,
        _optional_float("smoothing", smoothing),
        _count("genus", genus),
        _optional_float("closing", closing),
        None if vertices is None else _count("vertices", vertices),
        None if times is None else [float(t) for t in times],
        _count("relax_iterations", relax_iterations),
        bool(keep_going),
        progress,
    )
    report = json.loads(found["report"])
    report["voxel_size"] = found["voxel_size"]
    return Sequence(
        found["positions"],
        found["faces"],
        None,
        found["times"],
        None,
        report.get("warnings", []),
        str(path),
        report,
    )


def _level_text(level: Union[str, float]) -> str:
    """``level`` as the library parses it: ``"auto"`` (Otsu's) or a number."""
    if isinstance(level, str):
        return level
    if isinstance(level, (int, float)) and not isinstance(level, bool):
        return repr(float(level))
    raise ValueError(f"level must be \"auto\" or a number, got {level!r}")


def _triple(name: str, value: Any) -> Tuple[float, float, float]:
    try:
        x, y, z = (float(c) for c in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three numbers (x, y, z), got {value!r}") from None
    return (x, y, z)


def sample_volume(
    volumes: Any,
    positions: Any,
    faces: Any,
    voxel_size: Optional[SequenceOf[float]] = None,
    *,
    origin: SequenceOf[float] = (0.0, 0.0, 0.0),
    smoothing: Optional[float] = None,
    shell: Optional[Tuple[float, float]] = None,
    layers: int = 9,
    reduce: str = "max",
    allow_outside: bool = False,
    channel: Optional[int] = None,
    resolution_level: int = 0,
) -> Dict[str, Any]:
    """A microscope recording read onto a moving surface (``meshflow sample``): the grey
    value of every vertex in every frame, for :func:`compute_flow`.

    Volume ``k`` is read on frame ``k`` of the surface: at each vertex ``x_i``, ``layers``
    trilinear samples along its unit normal ``n_i`` (the corner-angle-weighted mean of its
    faces' normals, outward for faces counter-clockwise seen from outside, as
    :func:`fit_surface` returns them), evenly spaced over ``[−inside, +outside]``, reduced
    to one value. A vertex whose shell leaves the volume at any layer gets 0, is counted in
    ``outside`` and flagged in ``no_data``. A frame with more than half of its vertices
    outside its volume is refused (``ValueError`` naming the voxel size, origin, the
    volume's and the surface's extent): most likely the voxel size is in other units than the
    positions, or missing; ``allow_outside=True`` samples anyway.

    Parameters
    ----------
    volumes : (K, Z, Y, X) array, a list of K (Z, Y, X) arrays, or a path
        One 3-D image per frame in NumPy's ``(z, y, x)`` order (as tifffile and h5py read
        stacks), float32, float64 or any integer dtype (uint8, uint16 …); stored as float32.
        Voxel ``(k, j, i)`` is the value at ``origin + (i·d_x, j·d_y, k·d_z)``. A path names a
        recording on disk as :func:`read_volumes` reads it (``.npy``, TIFF, ImageJ
        hyperstack, OME-Zarr, a directory): it is read and sampled one frame at a time, so
        that only one frame is ever held, as ``meshflow sample`` does.
    positions : (K, V, 3) array of float
        The surface's vertex positions per frame, in the same physical units.
    faces : (F, 3) array of int
        Its triangles (every vertex in one; no welding is done here).
    voxel_size : (d_x, d_y, d_z)
        The voxel's sides in the surface's units (e.g. µm), in ``(x, y, z)`` order. Required
        for arrays; for a path, the files' metadata gives it where this is not given.
    origin : (x, y, z)
        The position of voxel ``(0, 0, 0)``'s centre.
    channel, resolution_level : int
        For a path: the channel and pyramid level (:func:`read_volumes`).
    smoothing : float, optional
        ``σ`` of a Gaussian applied to each volume first (physical units; 0: none); default
        two of the smallest voxel sides.
    shell : (inside, outside), optional
        How far the samples reach against and along the normal (physical units); default two
        of the largest voxel sides each way.
    layers : int
        Samples across the shell (1: at the surface only).
    reduce : {"max", "mean", "layer:L"}
        The brightest sample (a maximum-intensity projection within the shell), their mean,
        or sample ``L`` (0: the innermost).
    allow_outside : bool
        Sample frames whose surface lies mostly outside the volume instead of refusing them.

    Returns
    -------
    dict
        ``values`` (K, V) float64; ``outside``: per frame, how many vertices' shells left the
        volume (their value is 0); ``no_data`` (K, V) bool, which they are; ``shell``
        ``(inside, outside, layers)`` and ``smoothing`` ``σ`` as used. For a path, also
        ``voxel_size`` as used and ``voxel_size_source``.

    Errors are ``ValueError`` with the library's message: a volume that is not finite
    (naming the frame and voxel), a voxel size that is not positive, as many volumes as
    frames, faces that name no vertex, ``layer:L`` beyond the shell.

    Example::

        surface = meshflow.fit_surface(cells)
        sampled = meshflow.sample_volume(stack, surface["positions"], surface["faces"],
                                         voxel_size=(0.4, 0.4, 2.0), reduce="max")
        flow = meshflow.compute_flow(surface["positions"], surface["faces"], sampled["values"])
    """
    positions = _floats("positions", positions, 3, 3)
    faces = _faces(faces)
    if shell is not None:
        try:
            inside, outside = (float(d) for d in shell)
        except (TypeError, ValueError):
            raise ValueError(
                f"shell must be two distances (inside, outside), got {shell!r}"
            ) from None
        shell = (inside, outside)
    layer_count = _count("layers", layers)
    if layer_count is None:
        raise ValueError("layers must be a whole number ≥ 1, not None")
    if not isinstance(reduce, str):
        raise ValueError(f"reduce must be \"max\", \"mean\" or \"layer:L\", got {reduce!r}")
    if _is_path(volumes):
        return _meshflow.sample_volume_file(
            _path(volumes),
            positions,
            faces,
            _optional_triple("voxel_size", voxel_size),
            _triple("origin", origin),
            _count("channel", channel),
            _level("resolution_level", resolution_level),
            _optional_float("smoothing", smoothing),
            shell,
            layer_count,
            reduce,
            bool(allow_outside),
        )
    if channel is not None or resolution_level != 0:
        raise ValueError("channel and resolution_level apply to a path, not to arrays")
    if voxel_size is None:
        raise ValueError("voxel_size is required with arrays: (d_x, d_y, d_z) in the surface's units")
    return _meshflow.sample_volume(
        _volume_frames(volumes),
        positions,
        faces,
        _triple("voxel_size", voxel_size),
        _triple("origin", origin),
        _optional_float("smoothing", smoothing),
        shell,
        layer_count,
        reduce,
        bool(allow_outside),
    )
