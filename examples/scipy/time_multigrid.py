"""Prototype coarsenings in time for meshflow's multigrid preconditioner, on a written system.

The space-time system is block tridiagonal in time: diagonal blocks D_s (one per slab, 2V x 2V),
links X_s at (s + 1, s), lumped (one 2x2 block per vertex) on the finest level. The V-cycle is
meshflow's (src/flow/solve/multigrid.rs): forward odd-even sweep (even slabs, then odd, exact
slab solves), restriction, coarse cycle, prolongation, backward sweep (odd, then even) on the
new residual; PCG to a relative residual of 1e-8. Coarsenings:

  pairs    meshflow's: slabs 2k, 2k+1 merge, u_2k = u_k, u_2k+1 = T u_k (T: per vertex the
           polar rotation of -X_ii), Galerkin P^T A P less half the coarse links' coupling
           (the links halved, their shares |X|, |X^T| taken off the diagonal blocks).
  vertex   the even slabs are the coarse ones, u_2k+1 = (T+ u_k + T- u_k+1) / 2 (linear
           interpolation in time with the links' rotations), Galerkin P^T A P.
  hybrid:R vertex-centred levels while the links carry a share R of the diagonal (the median
           over slabs and vertices of |X_ii| / |D_ii|, 1/2 where the time coupling dominates),
           pairs below (halved only when no vertex-centred level came before).

    cargo run --release --example space_time_system -- 32 24 20 0.01 0.01 /tmp/system
    python3 examples/scipy/time_multigrid.py pairs,vertex,hybrid:0.497 /tmp/system [...]

prints the PCG iterations of each coarsening per system (docs/scaling.md, "Vertex-centred
coarsening in time"). Dense 2x2 loops in Python: systems of a few ten thousand unknowns.
"""

import sys

import numpy as np
import scipy.io
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def load(directory):
    a = scipy.io.mmread(f"{directory}/A.mtx").tocsr()
    b = np.load(f"{directory}/b.npy")
    n = int(open(f"{directory}/slab_dimension.txt").read())
    return a, b, n


def vertex_blocks(m, n):
    """The 2x2 diagonal vertex blocks of the n x n sparse m, as an (n/2, 2, 2) array."""
    blocks = np.zeros((n // 2, 2, 2))
    m = m.tocoo()
    same = m.row // 2 == m.col // 2
    np.add.at(blocks, (m.row[same] // 2, m.row[same] % 2, m.col[same] % 2), m.data[same])
    return blocks


def polar(m):
    """The rotation of the polar decomposition of each 2x2 block."""
    angle = np.arctan2(m[:, 1, 0] - m[:, 0, 1], m[:, 0, 0] + m[:, 1, 1])
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def spd_sqrt(s):
    root_det = np.sqrt(np.maximum(np.linalg.det(s), 0.0))
    t = np.sqrt(np.maximum(np.trace(s, axis1=1, axis2=2) + 2 * root_det, 0.0))
    root = (s + root_det[:, None, None] * np.eye(2)) / np.where(t > 0, t, 1.0)[:, None, None]
    return np.where((t > 0)[:, None, None], root, 0.0)


def block_diagonal(blocks):
    return sp.block_diag(list(blocks), format="csr")


class Level:
    def __init__(self, a, n):
        self.a, self.n, self.slabs = a.tocsr(), n, a.shape[0] // n
        cut = lambda r, c: self.a[r * n:(r + 1) * n, c * n:(c + 1) * n]
        self.d = [cut(s, s).tocsc() for s in range(self.slabs)]
        self.x = [cut(s + 1, s).tocsr() for s in range(self.slabs - 1)]
        self.lu = [spla.splu(d) for d in self.d]

    def slab(self, v, s):
        return v[s * self.n:(s + 1) * self.n]

    def sweep(self, r, first, second):
        """Solves the slabs of parity `first` with r alone, then those of `second` with them."""
        z = np.zeros_like(r)
        for s in range(first, self.slabs, 2):
            z[s * self.n:(s + 1) * self.n] = self.lu[s].solve(self.slab(r, s))
        for s in range(second, self.slabs, 2):
            rs = self.slab(r, s).copy()
            if s > 0:
                rs -= self.x[s - 1] @ self.slab(z, s - 1)
            if s + 1 < self.slabs:
                rs -= self.x[s].T @ self.slab(z, s + 1)
            z[s * self.n:(s + 1) * self.n] = self.lu[s].solve(rs)
        return z

    def share(self):
        """Median over slabs of the median over vertices of |X_ii| / |D_ii|."""
        shares = [
            np.median(
                np.linalg.norm(vertex_blocks(x, self.n), axis=(1, 2))
                / np.linalg.norm(vertex_blocks(d, self.n), axis=(1, 2))
            )
            for x, d in zip(self.x, self.d)
        ]
        return np.median(shares) if shares else 0.0


def forward_transports(level):
    """T_s per vertex from slab s to s + 1."""
    return [block_diagonal(polar(-vertex_blocks(x, level.n))) for x in level.x]


def pairs_prolongation(level):
    t = forward_transports(level)
    coarse = (level.slabs + 1) // 2
    grid = [[None] * coarse for _ in range(level.slabs)]
    for s in range(level.slabs):
        grid[s][s // 2] = sp.identity(level.n, format="csr") if s % 2 == 0 else t[s - 1]
    return sp.bmat(grid, format="csr")


def vertex_prolongation(level):
    t = forward_transports(level)
    coarse = (level.slabs + 1) // 2
    grid = [[None] * coarse for _ in range(level.slabs)]
    for s in range(level.slabs):
        k = s // 2
        if s % 2 == 0:
            grid[s][k] = sp.identity(level.n, format="csr")
        elif s + 1 < level.slabs:
            grid[s][k] = 0.5 * t[s - 1]
            grid[s][k + 1] = 0.5 * t[s].T
        else:
            grid[s][k] = t[s - 1]
    return sp.bmat(grid, format="csr")


def halve_coupling(a, n):
    """Halves each link and takes its lumped shares |X|, |X^T| off the two diagonal blocks."""
    a = a.tolil()
    for s in range(a.shape[0] // n - 1):
        rows, cols = slice((s + 1) * n, (s + 2) * n), slice(s * n, (s + 1) * n)
        x = a[rows, cols].tocsr() * 0.5
        a[rows, cols], a[cols, rows] = x, x.T
        blocks = vertex_blocks(x, n)
        before = spd_sqrt(np.einsum("kji,kjl->kil", blocks, blocks))
        after = spd_sqrt(np.einsum("kij,klj->kil", blocks, blocks))
        a[cols, cols] = a[cols, cols] - block_diagonal(before)
        a[rows, rows] = a[rows, rows] - block_diagonal(after)
    return a.tocsr()


def hierarchy(a, n, kind):
    levels, prolongations = [Level(a, n)], []
    vertex_so_far, any_vertex = True, False
    while levels[-1].slabs > 1:
        level = levels[-1]
        if kind.startswith("hybrid:"):
            vertex_so_far = vertex_so_far and level.share() >= float(kind.split(":")[1])
            vertex = vertex_so_far
        else:
            vertex = kind == "vertex"
        any_vertex = any_vertex or vertex
        p = vertex_prolongation(level) if vertex else pairs_prolongation(level)
        coarse = (p.T @ level.a @ p).tocsr()
        if not any_vertex:
            coarse = halve_coupling(coarse, n)
        prolongations.append(p)
        levels.append(Level(coarse, n))
    return levels, prolongations


def v_cycle(levels, prolongations, l, r):
    level = levels[l]
    z = level.sweep(r, 0, 1)
    if l + 1 == len(levels):
        return z
    coarse = v_cycle(levels, prolongations, l + 1, prolongations[l].T @ (r - level.a @ z))
    z = z + prolongations[l] @ coarse
    return z + level.sweep(r - level.a @ z, 1, 0)


def pcg(apply, b, preconditioner, tolerance=1e-8, limit=300, flexible=False):
    """CG on the operator `apply` from zero to a relative residual of `tolerance`: the solution
    and the iterations taken (`limit` if it did not get there). `flexible`: Notay's flexible CG
    with one direction kept (step (p, r) / (p, Ap), next direction A-orthogonal to the last), for
    a preconditioner that is not symmetric; the same as CG for one that is."""
    x, r = np.zeros_like(b), b.copy()
    z = preconditioner(r)
    p, rz, norm = z.copy(), r @ z, np.linalg.norm(b)
    for iteration in range(1, limit + 1):
        ap = apply(p)
        curvature = p @ ap
        step = (p @ r if flexible else rz) / curvature
        x += step * p
        r -= step * ap
        if np.linalg.norm(r) / norm < tolerance:
            return x, iteration
        z = preconditioner(r)
        rz, previous = r @ z, rz
        p = z + (-(z @ ap) / curvature if flexible else rz / previous) * p
    return x, limit


def pcg_iterations(a, b, preconditioner, tolerance=1e-8, limit=300):
    return pcg(lambda v: a @ v, b, preconditioner, tolerance, limit)[1]


def main():
    kinds, directories = sys.argv[1].split(","), sys.argv[2:]
    for directory in directories:
        a, b, n = load(directory)
        results = []
        for kind in kinds:
            levels, prolongations = hierarchy(a, n, kind)
            cycle = lambda r: v_cycle(levels, prolongations, 0, r)
            results.append(f"{kind} {pcg_iterations(a, b, cycle)}")
        print(f"{directory}: " + ", ".join(results), flush=True)


if __name__ == "__main__":
    main()
