"""Optical flow on a moving triangle mesh: an independent NumPy/SciPy implementation of the
discretization defined in /work/shared/design/discretization.md (the meshflow contract).

    python3 flow_pipeline.py FRAMES_DIR --intensity I.npy --alpha A --beta B --gamma G \
        [--times t0,t1,...] [--tolerance 1e-8] [--solver gs|jacobi|direct] \
        [--factor-precision single|double] [--time-coupling lumped|consistent] \
        [--boundary neumann|dirichlet] --out OUTDIR

Writes OUTDIR/flow_intrinsic.npy (S, V, 2), flow.npy (S, V, 3) and summary.json (energy,
residual, iterations, solver, seconds per stage, peak memory).

Math (section numbers of the contract)
--------------------------------------
K frames give S = K-1 slabs (§3). Slab s has edge lengths = mean of frames s and s+1,
I_mid = (I_s + I_{s+1})/2 and tau = (I_{s+1} - I_s)/dt_s per vertex. Each face (a, b, c) is laid
out as p_a = 0, p_b = (l_ab, 0), p_c above the x-axis (§4); its corner angles come from the
cotangents, its area from Kahan's Heron formula. Around vertex i the corners are ordered
counter-clockwise starting at the boundary edge (boundary vertex) or at the corner in the
lowest-numbered face (interior vertex); the polar angle of a corner's first edge is
s_i * (sum of the preceding corner angles), s_i = 2 pi / Theta_i inside and 1 on the boundary.
Corner rotation r = phi - polar + theta (1 - s_i)/2 with phi = 0, pi - theta_b, pi + theta_a
maps vertex-frame vectors to the face frame.

Per face and slab (§5) with cotan stiffness S, consistent mass m and R_a = Rot(r_a):
block(a, b) = dt [(gamma S_ab + beta m_ab) Rot(r_b - r_a) + m_ab g_a g_b^T], g_a = R_a^T G
(G the face gradient of I_mid), f_a = dt (m tau)_a g_a, constant dt tau^T m tau.
Time coupling (§6) between slabs s, s+1 with c = gamma / (alpha^2 h_s), the polar rotation
angle q_T of J_T = E^{s+1} (E^s)^-1 and the mid area: lumped, c Abar/3 on each diagonal and
-c Abar/3 Rot(q + r^s_a - r^{s+1}_a) in the (s+1, s) block at vertex a; consistent, the
scalar matrix c Abar/12 (1 + I) in place of c Abar/3 I, with Rot(q + r^s_b - r^{s+1}_a) in
block (a, b). The unknowns are ordered (slab, vertex, component); the system A u = -f is
solved to ||A u + f|| <= tol ||f|| and E(u) = u^T A u + 2 f^T u + const is reported. The
output frames (§7) are geometry-central's vertex tangent bases on frame s, using the slab
polar angles.

Implementation notes
--------------------
- OBJ frames are parsed with one regular expression per line kind and np.fromstring, on two
  processes (number parsing holds the GIL): about 0.1 s per 48k-vertex frame.
- Everything per face is vectorized over faces; slabs are processed on two threads (large
  NumPy operations release the GIL). The fan order is found once per connectivity: the
  successor of a corner is the twin of its incoming halfedge, cycles are cut at the fan's
  start, and the exclusive prefix sums of the corner angles along each fan (the polar angles)
  are computed by pointer doubling (log2(valence) vectorized steps, no loop over vertices).
- The sparsity pattern of one slab (2x2 blocks for every vertex pair sharing an edge) and the
  slot of every element entry in it are computed once; each slab block is one np.bincount.
  A is kept as its blocks D_s, X_s, X_s^T (CSR) and applied block by block, which needs no
  global matrix (the direct solver builds one with scipy.sparse.block_array).
- Solvers (all stop at ||A u + f|| <= tol ||f||):
  * gs (default): scipy.sparse.linalg.cg preconditioned by a symmetric block Gauss-Seidel
    sweep over the slabs (forward, then backward), each slab block solved exactly with its
    SuperLU factor. This is meshflow's preconditioner: the spatial coupling is treated
    exactly, the time coupling by the sweep. On the paper's torus (255x190, 20 frames,
    alpha = gamma = 1) it needs 14 iterations against block Jacobi's 37, which more than pays
    for its 2S - 1 instead of S slab solves per application.
  * jacobi: cg with the same slab factors applied block-Jacobi, the slab solves on two
    threads. SuperLU's triangular solves are memory-bound and gain little from the second
    core, so it stays behind gs (and so did gs with the slabs split into two runs swept in
    parallel: 18 iterations, 4 % faster solves, not kept).
  * direct: one SuperLU factorization of the whole space-time matrix. Its fill grows like a
    3-D problem's: 117k unknowns (64x48 torus, 20 frames) already take 232 s and 4.3 GB, so
    it is only usable for small cases.
- Slab factors: splu in SymmetricMode with diag_pivot_thresh=0 (the blocks are symmetric
  positive definite, so the ordering stays symmetric and no pivoting adds fill), on blocks
  permuted once by a minimum-degree ordering of the vertex graph (SuperLU's MMD on A^T + A of
  a V x V graph Laplacian, both components of a vertex kept together) and factored with
  permc_spec="NATURAL": one ordering for all slabs instead of one per slab, and 3 % less
  fill than MMD on the DOF graph (COLAMD and MMD on A^T A fill almost twice as much). Factors are
  single precision by default (CG stays in double): factorization is twice as fast, memory
  about a quarter lower, the iteration count unchanged; a block that is singular in single
  precision is factored in double. Factorizations run on two threads (splu releases the GIL).
"""
import argparse
import json
import re
import resource
import time
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

THREADS = 2
SOLVERS = ("gs", "jacobi", "direct")


# ----------------------------------------------------------------------------------------------
# Input

def natural_key(path):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name)]


_V_LINE = re.compile(rb"^[ \t]*v[ \t]+(\S+[ \t]+\S+[ \t]+\S+)", re.M)  # x y z only
_F_LINE = re.compile(rb"^[ \t]*f[ \t]+([^\r\n]*)", re.M)
_REFERENCE_TAIL = re.compile(rb"/\S*")


def read_obj(path, want_faces):
    """Positions (V, 3) and, with `want_faces`, triangles (F, 3) of an OBJ file. Face references
    may be `v`, `v/t`, `v//n` or `v/t/n`, negative ones count back from the last vertex (as
    when all `v` lines come first); polygons are fan-triangulated."""
    data = Path(path).read_bytes()
    positions = np.fromstring(b" ".join(_V_LINE.findall(data)), sep=" ").reshape(-1, 3)
    if not want_faces:
        return positions, None
    lines = _F_LINE.findall(data)
    corners = np.fromstring(_REFERENCE_TAIL.sub(b"", b"\n".join(lines)), sep=" ",
                            dtype=np.int64)
    counts = np.array([len(l.split()) for l in lines])
    if np.all(counts == 3):
        faces = corners.reshape(-1, 3)
    else:
        if np.any(counts < 3):
            raise ValueError(f"{path}: a face has fewer than three vertices")
        first = np.repeat(np.cumsum(counts) - counts, counts - 2)
        second = np.concatenate([o + np.arange(1, c - 1) for o, c in
                                 zip(np.cumsum(counts) - counts, counts)])
        faces = corners[np.stack([first, second, second + 1], 1)]
    faces = np.where(faces < 0, faces + len(positions), faces - 1)
    if faces.min() < 0 or faces.max() >= len(positions):
        raise ValueError(f"{path}: a face refers to a vertex that does not exist")
    return positions, faces


def read_positions(path):
    return read_obj(path, want_faces=False)[0]


def read_frames(frames_dir):
    """Positions (K, V, 3) of the .obj files (natural order) and the faces of the first one.
    Frames are parsed on THREADS processes (parsing numbers holds the GIL)."""
    paths = sorted(Path(frames_dir).glob("*.obj"), key=natural_key)
    if len(paths) < 2:
        raise ValueError(f"{frames_dir}: need at least two .obj frames")
    with ProcessPoolExecutor(THREADS, mp_context=multiprocessing.get_context("fork")) as pool:
        rest = pool.map(read_positions, paths[1:])
        first, faces = read_obj(paths[0], want_faces=True)
        frames = [first] + list(rest)
    if any(f.shape != first.shape for f in frames):
        raise ValueError("all frames must have the same number of vertices")
    return np.stack(frames), faces


# ----------------------------------------------------------------------------------------------
# Connectivity: twins, fans, sparsity pattern (once per mesh)

@dataclass
class Pattern:
    """A CSR pattern (square, 2V rows) with the position of each entry's transpose."""
    indptr: np.ndarray
    indices: np.ndarray
    transpose: np.ndarray

    @property
    def rows(self):
        return np.repeat(np.arange(len(self.indptr) - 1), np.diff(self.indptr))

    def matrix(self, data):
        n = len(self.indptr) - 1
        return sp.csr_array((data, self.indices, self.indptr), shape=(n, n))


@dataclass
class Connectivity:
    faces: np.ndarray          # (F, 3)
    n_vertices: int
    corner_vertex: np.ndarray  # (3F,) vertex of corner 3f + k (= tail of halfedge 3f + k)
    boundary: np.ndarray       # (V,) bool
    fan_prev: np.ndarray       # (3F + 1,) previous corner in the fan; 3F (sentinel) at the start
    fan_jumps: list            # fan_prev composed with itself 2^k times, while not all sentinel
    fan_last: np.ndarray       # (V,) last corner of each fan
    vertex: Pattern            # 2x2 blocks of vertex pairs that share an edge
    slots: np.ndarray          # (F, 3, 3, 2, 2) position in `vertex` of each element entry
    lumped: Pattern            # 2x2 diagonal blocks only


def build_connectivity(faces, n_vertices):
    n_corners = 3 * len(faces)
    tail = faces.ravel()
    head = faces[:, [1, 2, 0]].ravel()
    if np.any(tail == head) or np.any(faces[:, 0] == faces[:, 2]):
        raise ValueError("a face repeats a vertex")
    if np.any(np.bincount(tail, minlength=n_vertices) == 0):
        raise ValueError("a vertex is not used by any face")
    twin = halfedge_twins(tail, head, n_vertices)
    incoming = np.arange(n_corners).reshape(-1, 3)[:, [2, 0, 1]].ravel()
    fan_next = twin[incoming]
    on_boundary = twin < 0
    if np.any(np.bincount(tail[on_boundary], minlength=n_vertices) > 1):
        raise ValueError("a vertex has more than one fan (non-manifold)")
    boundary = np.zeros(n_vertices, bool)
    boundary[tail[on_boundary]] = True
    start = np.empty(n_vertices, np.int64)
    _, first_corner = np.unique(tail, return_index=True)
    start[:] = first_corner
    start[tail[on_boundary]] = np.flatnonzero(on_boundary)
    fan_next[np.isin(fan_next, start)] = -1
    prev = np.full(n_corners + 1, n_corners)
    has_next = fan_next >= 0
    prev[fan_next[has_next]] = np.flatnonzero(has_next)
    starts = np.zeros(n_corners, bool)
    starts[start] = True
    if np.any((prev[:-1] == n_corners) != starts):
        raise ValueError("a vertex has more than one fan (non-manifold)")
    fan_last = np.empty(n_vertices, np.int64)
    fan_last[tail[~has_next]] = np.flatnonzero(~has_next)
    vertex, slots = vertex_pattern(faces, n_vertices)
    return Connectivity(faces, n_vertices, tail, boundary, prev, pointer_jumps(prev),
                        fan_last, vertex, slots, lumped_pattern(n_vertices))


def halfedge_twins(tail, head, n_vertices):
    """The opposite halfedge of each halfedge, -1 on the boundary."""
    key = tail * n_vertices + head
    order = np.argsort(key)
    sorted_keys = key[order]
    if np.any(sorted_keys[1:] == sorted_keys[:-1]):
        raise ValueError("an edge has more than two faces or its faces disagree in orientation")
    reverse = head * n_vertices + tail
    at = np.minimum(np.searchsorted(sorted_keys, reverse), len(key) - 1)
    return np.where(sorted_keys[at] == reverse, order[at], -1)


def pointer_jumps(prev):
    """[prev, prev∘prev, prev^4, ...] while some pointer has not reached the sentinel."""
    sentinel = len(prev) - 1
    jumps, pointer = [], prev
    while np.any(pointer != sentinel):
        if len(jumps) > np.log2(len(prev)) + 1:
            raise ValueError("a vertex has more than one fan (non-manifold)")
        jumps.append(pointer)
        pointer = pointer[pointer]
    return jumps


def fan_exclusive_sums(conn, values):
    """Per corner, the sum of `values` over the corners before it in its vertex's fan."""
    padded = np.append(values, 0.0)
    acc = padded[conn.fan_prev]
    for pointer in conn.fan_jumps:
        acc = acc + acc[pointer]
    return acc[:-1]


def vertex_pattern(faces, n_vertices):
    """The 2x2-block pattern of vertex pairs (i, j) sharing a face, and the slot of entry
    (f, a, b, ci, cj) = row 2 faces[f, a] + ci, column 2 faces[f, b] + cj."""
    rows = np.broadcast_to(faces[:, :, None], (len(faces), 3, 3))
    cols = np.broadcast_to(faces[:, None, :], (len(faces), 3, 3))
    pairs, pair_of = np.unique((rows * n_vertices + cols).ravel(), return_inverse=True)
    pi, pj = pairs // n_vertices, pairs % n_vertices
    vptr = np.concatenate([[0], np.cumsum(np.bincount(pi, minlength=n_vertices))])
    degree = np.diff(vptr)
    ci, cj = np.arange(2)[:, None], np.arange(2)[None, :]

    def position(i, pair, ci, cj):
        """Row 2i + ci of the pattern lists the neighbours j of i in order, two columns each."""
        return 2 * vptr[i] + 2 * pair + 2 * ci * degree[i] + cj

    entry = position(pi[:, None, None], np.arange(len(pairs))[:, None, None], ci, cj)
    indices = np.empty(4 * len(pairs), np.int64)
    indices[entry] = 2 * pj[:, None, None] + cj
    transposed_pair = np.searchsorted(pairs, pj * n_vertices + pi)
    transpose = np.empty_like(indices)
    transpose[entry] = position(pj[:, None, None], transposed_pair[:, None, None], cj, ci)
    indptr = np.empty(2 * n_vertices + 1, np.int64)
    indptr[0:-1:2] = 4 * vptr[:-1]
    indptr[1::2] = 4 * vptr[:-1] + 2 * degree
    indptr[-1] = 4 * vptr[-1]
    pattern = Pattern(indptr, indices.astype(np.int32), transpose)
    slots = position(rows[..., None, None], pair_of.reshape(rows.shape)[..., None, None], ci, cj)
    return pattern, slots


def lumped_pattern(n_vertices):
    """2x2 diagonal blocks; data laid out (vertex, row, column)."""
    dofs = np.arange(2 * n_vertices)
    indices = ((dofs // 2 * 2)[:, None] + np.arange(2)).ravel().astype(np.int32)
    transpose = np.arange(4 * n_vertices).reshape(-1, 2, 2).transpose(0, 2, 1).ravel()
    return Pattern(2 * np.arange(2 * n_vertices + 1), indices, transpose)


# ----------------------------------------------------------------------------------------------
# Geometry of one slab (§3, §4)

@dataclass
class SlabGeometry:
    area: np.ndarray       # (F,)
    cot: np.ndarray        # (F, 3)
    theta: np.ndarray      # (F, 3) corner angles
    layout: np.ndarray     # (F, 3): x of p_b, x and y of p_c
    polar: np.ndarray      # (F, 3) vertex-frame polar angle of each corner's first edge
    rotation: np.ndarray   # (F, 3) r_{T,i}


def face_lengths(conn, positions):
    """(K, F, 3) lengths l_ab, l_bc, l_ca of every face in every frame."""
    def lengths(frame):
        edges = frame[conn.faces[:, [1, 2, 0]]] - frame[conn.faces]
        return np.sqrt(np.einsum("fkd,fkd->fk", edges, edges))
    return np.stack([lengths(frame) for frame in positions])


def kahan_area(lengths):
    a, b, c = np.moveaxis(np.sort(lengths, axis=-1)[..., ::-1], -1, 0)
    product = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    return 0.25 * np.sqrt(np.maximum(product, 0.0)), a


def slab_geometry(conn, lengths):
    area, longest = kahan_area(lengths)
    if np.any(area <= np.finfo(float).eps * longest ** 2):
        raise ValueError(f"degenerate face {int(np.argmin(area / longest ** 2))}")
    sq = lengths ** 2
    cot = (sq + sq[:, [2, 0, 1]] - sq[:, [1, 2, 0]]) / (4.0 * area[:, None])
    theta = np.arctan2(1.0, cot)
    angle_sum = np.bincount(conn.corner_vertex, theta.ravel(), conn.n_vertices)
    scale = np.where(conn.boundary, 1.0, 2.0 * np.pi / angle_sum)
    corner_scale = scale[conn.faces]
    polar = corner_scale * fan_exclusive_sums(conn, theta.ravel()).reshape(-1, 3)
    first_edge = np.stack([np.zeros(len(theta)), np.pi - theta[:, 1], np.pi + theta[:, 0]], 1)
    rotation = first_edge - polar + theta * (1.0 - corner_scale) / 2.0
    layout = np.stack([lengths[:, 0], lengths[:, 2] * np.cos(theta[:, 0]),
                       lengths[:, 2] * np.sin(theta[:, 0])], 1)
    return SlabGeometry(area, cot, theta, layout, polar, rotation)


# ----------------------------------------------------------------------------------------------
# Element matrices (§5) and time coupling (§6)

CONSISTENT = (np.ones((3, 3)) + np.eye(3)) / 12.0
LUMPED = np.eye(3) / 3.0


def rotation_blocks(cos, sin):
    """[[cos, -sin], [sin, cos]] as (..., 2, 2)."""
    out = np.empty(cos.shape + (2, 2))
    out[..., 0, 0] = out[..., 1, 1] = cos
    out[..., 0, 1], out[..., 1, 0] = -sin, sin
    return out


def cotan_stiffness(cot):
    """(F, 3, 3): S_ab = -cot(opposite corner)/2, rows summing to zero."""
    off = -0.5 * cot
    s = np.zeros((len(cot), 3, 3))
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        s[:, a, b] = s[:, b, a] = off[:, c]
    s[:, range(3), range(3)] = -s.sum(axis=2)
    return s


def face_gradient(geometry, values):
    """(F, 2) face-frame gradient of the P1 function with corner values (F, 3)."""
    x_b, x_c, y_c = geometry.layout.T
    v_a, v_b, v_c = values.T
    twice_area = 2.0 * geometry.area
    return np.stack([-y_c * (v_a - v_b), v_a * (x_c - x_b) - v_b * x_c + v_c * x_b],
                    1) / twice_area[:, None]


def slab_elements(geometry, weights, dt, intensity, rate, coupling):
    """Element matrices (F, 3, 3, 2, 2) of dt (D + beta M + gamma K) plus the time-coupling
    scalars `coupling` (F, 3, 3) on Rot(r_b - r_a); the right-hand side -f (F, 3, 2) and the
    energy constant."""
    mass = geometry.area[:, None, None] * CONSISTENT
    scalar = dt * (weights.gamma * cotan_stiffness(geometry.cot) + weights.beta * mass) + coupling
    c, s = np.cos(geometry.rotation), np.sin(geometry.rotation)
    cos_ab = scalar * (c[:, :, None] * c[:, None, :] + s[:, :, None] * s[:, None, :])
    sin_ab = scalar * (c[:, :, None] * s[:, None, :] - s[:, :, None] * c[:, None, :])
    gradient = face_gradient(geometry, intensity)
    g = np.stack([c * gradient[:, :1] + s * gradient[:, 1:],
                  c * gradient[:, 1:] - s * gradient[:, :1]], -1)          # (F, 3, 2) = R_a^T G
    data = dt * mass
    blocks = np.empty(mass.shape + (2, 2))
    for i, j in np.ndindex(2, 2):
        blocks[..., i, j] = data * (g[:, :, None, i] * g[:, None, :, j])
    blocks[..., 0, 0] += cos_ab
    blocks[..., 1, 1] += cos_ab
    blocks[..., 0, 1] -= sin_ab
    blocks[..., 1, 0] += sin_ab
    m_tau = np.einsum("fab,fb->fa", mass, rate)
    rhs = -dt * m_tau[..., None] * g
    constant = dt * np.einsum("fa,fa->", rate, m_tau)
    return blocks, rhs, constant


def polar_angle(before, after):
    """Angle of the rotation factor of J = E_after E_before^-1 (per face, upper-triangular E)."""
    x_b, x_c, y_c = before.layout.T
    x_b1, x_c1, y_c1 = after.layout.T
    j01 = (x_c1 - x_b1 * x_c / x_b) / y_c
    return np.arctan2(-j01, x_b1 / x_b + y_c1 / y_c)


# ----------------------------------------------------------------------------------------------
# The space-time system

@dataclass
class Weights:
    alpha: float
    beta: float
    gamma: float


@dataclass
class System:
    """A = blockdiag(D_s) + X_s at block (s+1, s) + X_s^T at (s, s+1)."""
    blocks: list   # D_s, CSR
    lower: list    # X_s, CSR
    upper: list    # X_s^T, CSR
    rhs: np.ndarray
    constant: float

    def matvec(self, x):
        x = x.reshape(len(self.blocks), -1)
        y = np.stack([block @ part for block, part in zip(self.blocks, x)])
        for s, (lower, upper) in enumerate(zip(self.lower, self.upper)):
            y[s + 1] += lower @ x[s]
            y[s] += upper @ x[s + 1]
        return y.ravel()

    def operator(self):
        size = len(self.rhs)
        return spla.LinearOperator((size, size), matvec=self.matvec, dtype=np.float64)

    def matrix(self):
        """The whole of A as one CSC matrix."""
        n = len(self.blocks)
        grid = [[None] * n for _ in range(n)]
        for s in range(n):
            grid[s][s] = self.blocks[s]
        for s in range(n - 1):
            grid[s + 1][s], grid[s][s + 1] = self.lower[s], self.upper[s]
        return sp.block_array(grid, format="csc")


def link_weight(weights, dt, s):
    return weights.gamma / (weights.alpha ** 2 * 0.5 * (dt[s] + dt[s + 1]))


def assemble(conn, lengths, intensity, times, weights, coupling, dirichlet, pool):
    """Slab geometries (kept for the push-forward) and the space-time system; slabs are
    assembled on the thread pool (NumPy releases the GIL in the large array operations)."""
    dt = np.diff(times)
    n_slabs = len(dt)
    geometries = list(pool.map(lambda s: slab_geometry(conn, 0.5 * (lengths[s] + lengths[s + 1])),
                               range(n_slabs)))
    n_links = n_slabs - 1 if np.isfinite(weights.alpha) else 0
    # c * mid area of every face, per link
    link_area = [link_weight(weights, dt, s) * 0.5 * (geometries[s].area + geometries[s + 1].area)
                 for s in range(n_links)]
    scalar = LUMPED if coupling == "lumped" else CONSISTENT

    def slab(s):
        time_weight = sum(link_area[k] for k in (s - 1, s) if 0 <= k < n_links)
        mid = 0.5 * (intensity[s] + intensity[s + 1])[conn.faces]
        rate = ((intensity[s + 1] - intensity[s]) / dt[s])[conn.faces]
        elements, f, constant = slab_elements(geometries[s], weights, dt[s], mid, rate,
                                              np.multiply.outer(time_weight, scalar))
        dofs = (2 * conn.faces[..., None] + np.arange(2)).ravel()
        return (np.bincount(conn.slots.ravel(), elements.ravel(), len(conn.vertex.indices)),
                np.bincount(dofs, f.ravel(), 2 * conn.n_vertices), constant)

    blocks, rhs, constants = zip(*pool.map(slab, range(n_slabs)))
    blocks, rhs = list(blocks), np.concatenate(rhs)
    if coupling == "lumped":
        links = [lumped_link(conn, geometries[s], geometries[s + 1], link_area[s] * LUMPED[0, 0])
                 for s in range(n_links)]
        link_pattern = conn.lumped
    else:
        links = [consistent_link(conn, geometries[s], geometries[s + 1],
                                 np.multiply.outer(link_area[s], CONSISTENT))
                 for s in range(n_links)]
        link_pattern = conn.vertex
    if dirichlet:
        fix_boundary(conn, blocks, links, link_pattern, rhs)
    return geometries, System([conn.vertex.matrix(d) for d in blocks],
                              [link_pattern.matrix(x) for x in links],
                              [link_pattern.matrix(x[link_pattern.transpose]) for x in links],
                              rhs, sum(constants))


def lumped_link(conn, before, after, weight):
    """X at each vertex: -sum over its corners of weight Rot(q + r^s - r^{s+1}) with weight
    c Abar/3 per face; data laid out (V, 2, 2)."""
    angle = polar_angle(before, after)[:, None] + before.rotation - after.rotation
    w = -weight[:, None]
    n = conn.n_vertices
    cos = np.bincount(conn.corner_vertex, (w * np.cos(angle)).ravel(), n)
    sin = np.bincount(conn.corner_vertex, (w * np.sin(angle)).ravel(), n)
    return np.stack([cos, -sin, sin, cos], 1).ravel()


def consistent_link(conn, before, after, scalar):
    """X block (a, b) of each face: -c mbar_ab Rot(q + r^s_b - r^{s+1}_a), on conn.vertex."""
    q = polar_angle(before, after)[:, None, None]
    angle = q + before.rotation[:, None, :] - after.rotation[:, :, None]
    elements = rotation_blocks(-scalar * np.cos(angle), -scalar * np.sin(angle))
    return np.bincount(conn.slots.ravel(), elements.ravel(), len(conn.vertex.indices))


def fix_boundary(conn, blocks, links, link_pattern, rhs):
    """Dirichlet: identity rows and columns, zero right-hand side at boundary DOFs."""
    fixed = np.repeat(conn.boundary, 2)
    rows, cols = conn.vertex.rows, conn.vertex.indices
    masked = fixed[rows] | fixed[cols]
    for data in blocks:
        data[masked] = np.where(rows[masked] == cols[masked], 1.0, 0.0)
    link_masked = fixed[link_pattern.rows] | fixed[link_pattern.indices]
    for data in links:
        data[link_masked] = 0.0
    rhs[np.tile(fixed, len(rhs) // len(fixed))] = 0.0


def energy(system, u):
    """E(u) = u^T A u + 2 f^T u + const (f = -rhs)."""
    return float(u @ system.matvec(u) - 2.0 * system.rhs @ u + system.constant)


# ----------------------------------------------------------------------------------------------
# Solvers

SPD_OPTIONS = {"diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}}
PRECISIONS = {"single": np.float32, "double": np.float64}


def vertex_ordering(conn):
    """A fill-reducing ordering of the 2V slab DOFs, shared by all slabs (same pattern):
    SuperLU's minimum degree on the vertex graph (computed by factoring a V x V graph
    Laplacian + I), each vertex's two components kept together."""
    n = conn.n_vertices
    rows = np.repeat(conn.faces, 3, axis=1).ravel()
    cols = np.tile(conn.faces, 3).ravel()
    graph = sp.csc_array((np.full(len(rows), -1.0), (rows, cols)), shape=(n, n))
    graph.setdiag(0.0)
    graph = (graph + sp.diags_array(1.0 - graph.sum(axis=0))).tocsc()
    order = np.argsort(spla.splu(graph, permc_spec="MMD_AT_PLUS_A", **SPD_OPTIONS).perm_c)
    return (2 * order[:, None] + np.arange(2)).ravel()


class SlabFactor:
    """SuperLU factor of a symmetric positive definite slab block in a given ordering (NATURAL
    inside SuperLU, diagonal pivots). Single precision halves the memory and is about twice as
    fast to factor; it is only a preconditioner (CG runs in double precision). A block that
    is singular in single precision is factored in double precision instead."""

    def __init__(self, block, order, precision):
        self.order = order
        permuted = block[order][:, order].tocsc()
        try:
            self.dtype = PRECISIONS[precision]
            self.lu = spla.splu(permuted.astype(self.dtype), permc_spec="NATURAL", **SPD_OPTIONS)
        except RuntimeError:
            self.dtype = np.float64
            self.lu = spla.splu(permuted, permc_spec="NATURAL", **SPD_OPTIONS)
        self.fill = self.lu.nnz

    def solve(self, r):
        x = np.empty(len(r))
        x[self.order] = self.lu.solve(r[self.order].astype(self.dtype))
        return x


def block_jacobi(factors, pool):
    def apply(r):
        parts = r.reshape(len(factors), -1)
        return np.concatenate(list(pool.map(lambda k: factors[k].solve(parts[k]),
                                            range(len(factors)))))
    return apply


def symmetric_gauss_seidel(factors, system):
    """z = (D + U)^-1 D (D + L)^-1 r: a forward sweep z_s = D_s^-1 (r_s - X_{s-1} z_{s-1}),
    then backward z_s -= D_s^-1 X_s^T z_{s+1} (2S - 1 slab solves)."""
    def apply(r):
        z = r.reshape(len(factors), -1).copy()
        z[0] = factors[0].solve(z[0])
        for s in range(1, len(factors)):
            z[s] = factors[s].solve(z[s] - system.lower[s - 1] @ z[s - 1])
        for s in range(len(factors) - 2, -1, -1):
            z[s] -= factors[s].solve(system.upper[s] @ z[s + 1])
        return z.ravel()
    return apply


def solve_pcg(conn, system, tolerance, solver, precision, pool, timings):
    """CG on A u = -f preconditioned with the exact slab factors, block Jacobi or symmetric
    block Gauss-Seidel; returns u, iterations and the factors' stored entries."""
    clock = time.perf_counter()
    order = vertex_ordering(conn)
    factors = list(pool.map(lambda block: SlabFactor(block, order, precision), system.blocks))
    timings["factor"] = time.perf_counter() - clock
    if solver == "jacobi" or not system.lower:
        apply = block_jacobi(factors, pool)
    else:
        apply = symmetric_gauss_seidel(factors, system)
    size = len(system.rhs)
    preconditioner = spla.LinearOperator((size, size), matvec=apply, dtype=np.float64)
    iterations = 0

    def count(_):
        nonlocal iterations
        iterations += 1

    clock = time.perf_counter()
    u, info = spla.cg(system.operator(), system.rhs, rtol=tolerance, atol=0.0, maxiter=5000,
                      M=preconditioner, callback=count)
    timings["solve"] = time.perf_counter() - clock
    if info != 0:
        raise RuntimeError(f"cg did not converge in {iterations} iterations")
    return u, iterations, sum(f.fill for f in factors)


def solve_direct(system, timings):
    """One SuperLU factorization of the whole space-time matrix."""
    clock = time.perf_counter()
    factor = spla.splu(system.matrix(), permc_spec="MMD_AT_PLUS_A", **SPD_OPTIONS)
    timings["factor"] = time.perf_counter() - clock
    clock = time.perf_counter()
    u = factor.solve(system.rhs)
    timings["solve"] = time.perf_counter() - clock
    return u, 1, factor.nnz


# ----------------------------------------------------------------------------------------------
# Output frames in R^3 (§7)

def normalize(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def vertex_frames(conn, geometry, positions):
    """(V, 2, 3): e1, e2 of every vertex on `positions` with the polar angles of `geometry`."""
    x = positions[conn.faces]                                        # (F, 3, 3)
    to_next = x[:, [1, 2, 0]] - x
    to_prev = x[:, [2, 0, 1]] - x
    face_normal = normalize(np.cross(to_next[:, 0], to_prev[:, 0]))
    corner_angle = np.arctan2(np.linalg.norm(np.cross(to_next, to_prev), axis=-1),
                              np.einsum("fkd,fkd->fk", to_next, to_prev))
    n = conn.n_vertices
    normal = normalize(np.stack([np.bincount(conn.corner_vertex,
                                             (corner_angle * face_normal[:, None, d]).ravel(), n)
                                 for d in range(3)], 1))
    # every corner's first edge, plus the closing edge of each boundary fan
    last = conn.fan_last[conn.boundary]
    edge = np.concatenate([to_next.reshape(-1, 3), to_prev.reshape(-1, 3)[last]])
    tail = np.concatenate([conn.corner_vertex, conn.corner_vertex[last]])
    polar = np.concatenate([geometry.polar.ravel(),
                            geometry.polar.ravel()[last] + geometry.theta.ravel()[last]])
    nt = normal[tail]
    projected = edge - nt * np.einsum("kd,kd->k", nt, edge)[:, None]
    vote = np.cos(polar)[:, None] * projected - np.sin(polar)[:, None] * np.cross(nt, projected)
    e1 = normalize(np.stack([np.bincount(tail, vote[:, d], n) for d in range(3)], 1))
    return np.stack([e1, np.cross(normal, e1)], 1)


def push_forward(conn, geometries, positions, u, pool):
    """(S, V, 3) R^3 vectors of the intrinsic flow u (S, V, 2), slab s on frame s."""
    def slab(s):
        return np.einsum("vc,vcd->vd", u[s], vertex_frames(conn, geometries[s], positions[s]))
    return np.stack(list(pool.map(slab, range(len(geometries)))))


# ----------------------------------------------------------------------------------------------
# Command line

def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("frames", type=Path, help="directory of frame_*.obj")
    parser.add_argument("--intensity", type=Path, required=True, help="(frames, V) .npy")
    parser.add_argument("--alpha", type=float, required=True, help="inf: frame-by-frame flow")
    parser.add_argument("--beta", type=float, required=True)
    parser.add_argument("--gamma", type=float, required=True)
    parser.add_argument("--times", help="t0,t1,... (default 0,1,2,...)")
    parser.add_argument("--tolerance", type=float, default=1e-8)
    parser.add_argument("--solver", choices=SOLVERS, default="gs")
    parser.add_argument("--factor-precision", choices=tuple(PRECISIONS), default="single",
                        help="precision of the slab factors (the preconditioner)")
    parser.add_argument("--time-coupling", choices=("lumped", "consistent"), default="lumped")
    parser.add_argument("--boundary", choices=("neumann", "dirichlet"), default="neumann")
    parser.add_argument("--out", type=Path, required=True)
    return parser.parse_args(argv)


def load_inputs(args):
    positions, faces = read_frames(args.frames)
    intensity = np.load(args.intensity).astype(np.float64)
    if intensity.shape != positions.shape[:2]:
        raise ValueError(f"intensity has shape {intensity.shape}, "
                         f"expected {positions.shape[:2]} (frames, vertices)")
    times = np.arange(len(positions), dtype=float) if args.times is None else \
        np.array([float(t) for t in args.times.split(",")])
    if len(times) != len(positions) or np.any(np.diff(times) <= 0):
        raise ValueError("need one strictly increasing time per frame")
    return positions, faces, intensity, times


def peak_memory_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def solve(conn, system, args, pool, timings):
    if args.solver == "direct":
        return solve_direct(system, timings)
    return solve_pcg(conn, system, args.tolerance, args.solver, args.factor_precision, pool,
                     timings)


def main(argv=None):
    args = parse_args(argv)
    if not (args.gamma > 0 and args.alpha > 0 and args.beta >= 0):
        raise ValueError("need gamma > 0, alpha > 0, beta >= 0")
    timings = {}
    start = clock = time.perf_counter()
    positions, faces, intensity, times = load_inputs(args)
    timings["read"] = time.perf_counter() - clock
    with ThreadPoolExecutor(THREADS) as pool:
        clock = time.perf_counter()
        conn = build_connectivity(faces, positions.shape[1])
        geometries, system = assemble(conn, face_lengths(conn, positions), intensity, times,
                                      Weights(args.alpha, args.beta, args.gamma),
                                      args.time_coupling, args.boundary == "dirichlet", pool)
        timings["assemble"] = time.perf_counter() - clock
        u, iterations, fill = solve(conn, system, args, pool, timings)
        clock = time.perf_counter()
        intrinsic = u.reshape(len(geometries), conn.n_vertices, 2)
        flow = push_forward(conn, geometries, positions, intrinsic, pool)
        timings["push_forward"] = time.perf_counter() - clock
    clock = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    np.save(args.out / "flow_intrinsic.npy", intrinsic)
    np.save(args.out / "flow.npy", flow)
    timings["write"] = time.perf_counter() - clock
    timings["total"] = time.perf_counter() - start
    b_norm = np.linalg.norm(system.rhs)
    summary = {
        "energy": energy(system, u),
        "energy_at_zero": system.constant,
        "relative_residual": float(np.linalg.norm(system.rhs - system.matvec(u)) / b_norm)
        if b_norm else 0.0,
        "iterations": iterations,
        "solver": args.solver,
        "factor_precision": args.factor_precision,
        "time_coupling": args.time_coupling,
        "boundary": args.boundary,
        "weights": {"alpha": args.alpha, "beta": args.beta, "gamma": args.gamma},
        "frames": len(times), "slabs": len(geometries),
        "vertices": conn.n_vertices, "faces": len(faces), "unknowns": len(u),
        "factor_nnz": int(fill),
        "seconds": timings,
        "cpu_seconds": time.process_time(),
        "load_average": os.getloadavg(),
        "peak_memory_mb": peak_memory_mb(),
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps({k: summary[k] for k in ("energy", "relative_residual", "iterations",
                                              "solver", "seconds", "peak_memory_mb")}))


if __name__ == "__main__":
    main()
