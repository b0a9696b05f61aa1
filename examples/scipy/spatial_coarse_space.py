"""Slab Gauss-Seidel PCG with a coarse space in space, on a written system.

What slows slab Gauss-Seidel at alpha = 1 (19 iterations on the paper-size torus) is not
constant in time (a coarse correction on the slab that merges all slabs does not help,
docs/scaling.md), so this tries the other direction: a coarse space that is fine in time and
coarse in space, P = diag(V, ..., V) with the same n x m basis V on every slab, coarse operator
A_c = P^T A P (block tridiagonal, m x m blocks), and the symmetric two-level preconditioner

    y = Q r,  z = y + M^-1 (r - A y),  z += Q (r - A z),     Q = P A_c^-1 P^T,

with M meshflow's odd-even slab Gauss-Seidel (exact f32 slab solves, SuperLU). Bases V:

  eig:M        the M lowest eigenvectors of the middle slab's block (shift-invert Lanczos)
  random:L,Q,M L random vectors through Q steps of the middle slab's solve (orthonormalized),
               then Rayleigh-Ritz with that block, the M lowest Ritz vectors kept
  aggregate:R  two fields per aggregate (greedy R-ring aggregates of vertices), constant up to
               the transport along a spanning tree (the polar rotation of the off-diagonal
               2x2 blocks), one step of smoothed aggregation; per slab
  A+B          both bases side by side (e.g. aggregate:3+random:64,3,64)

    cargo run --release --example space_time_system -- 128 95 20 1 1 /tmp/system
    python3 examples/scipy/spatial_coarse_space.py /tmp/system eig:16 random:64,3,64 aggregate:3

prints the PCG iterations to 1e-8 of each (docs/scaling.md, "A coarse space in space").
"""

import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from time_multigrid import load, pcg, polar


class Problem:
    def __init__(self, directory):
        self.a, self.b, self.n = load(directory)
        self.slabs = self.a.shape[0] // self.n
        self.blocks = [self.a[self.at(s), self.at(s)].tocsc() for s in range(self.slabs)]
        self.factors = [
            spla.splu(block.astype(np.float32), permc_spec="MMD_AT_PLUS_A") for block in self.blocks
        ]

    def at(self, s):
        return slice(s * self.n, (s + 1) * self.n)

    def solve(self, s, r):
        return self.factors[s].solve(r.astype(np.float32)).astype(np.float64)

    def links(self, z, s):
        return self.a[self.at(s), :] @ z - self.blocks[s] @ z[self.at(s)]

    def gauss_seidel(self, r):
        """meshflow's odd-even symmetric sweep: even, odd, even again."""
        z = np.zeros_like(r)
        for s in range(0, self.slabs, 2):
            z[self.at(s)] = self.solve(s, r[self.at(s)])
        for s in range(1, self.slabs, 2):
            z[self.at(s)] = self.solve(s, r[self.at(s)] - self.links(z, s))
        for s in range(0, self.slabs, 2):
            z[self.at(s)] -= self.solve(s, self.links(z, s))
        return z

    def iterations(self, preconditioner):
        return pcg(lambda x: self.a @ x, self.b, preconditioner)[1]

    def two_level(self, bases):
        """PCG iterations with the coarse space diag(bases)."""
        p = sp.block_diag([sp.csr_matrix(v) for v in bases]).tocsr()
        coarse = spla.splu((p.T @ (self.a @ p)).tocsc())

        def apply(r):
            y = p @ coarse.solve(p.T @ r)
            z = y + self.gauss_seidel(r - self.a @ y)
            return z + p @ coarse.solve(p.T @ (r - self.a @ z))

        return self.iterations(apply)


def lowest_eigenvectors(block, m):
    values, vectors = spla.eigsh(block, k=m, sigma=0, which="LM")
    return vectors[:, np.argsort(values)]


def randomized(problem, s, count, powers, kept, seed=1):
    y = np.random.default_rng(seed).standard_normal((problem.n, count))
    for _ in range(powers):
        y = np.column_stack([problem.solve(s, y[:, j]) for j in range(count)])
        y, _ = np.linalg.qr(y)
    _, ritz = np.linalg.eigh(y.T @ (problem.blocks[s] @ y))
    return y @ ritz[:, :kept]


def vertex_graph(block):
    c = block.tocoo()
    v = block.shape[0] // 2
    g = sp.csr_matrix((np.ones(c.nnz), (c.row // 2, c.col // 2)), shape=(v, v))
    g.setdiag(0)
    g.eliminate_zeros()
    return g.indptr, g.indices


def aggregates(graph, ring):
    """Greedy aggregates: each unaggregated vertex takes its unaggregated R-ring; a lone vertex
    joins a neighbour's aggregate. Returns (aggregate of each vertex, spanning-tree parent)."""
    ptr, ind = graph
    v = len(ptr) - 1
    aggregate, parent = -np.ones(v, int), -np.ones(v, int)
    count = 0
    for root in range(v):
        if aggregate[root] >= 0:
            continue
        members, front = [root], [root]
        aggregate[root] = count
        for _ in range(ring):
            grown = []
            for u in front:
                for w in ind[ptr[u]:ptr[u + 1]]:
                    if aggregate[w] < 0:
                        aggregate[w], parent[w] = count, u
                        grown.append(w)
            members += grown
            front = grown
        count += 1
    return aggregate, parent, count


def aggregation_basis(block, aggregate, parent, count):
    """Transported constants on each aggregate, smoothed by one damped block-Jacobi step."""
    v = len(aggregate)
    order = [u for u in np.argsort(_depth(parent))]
    rotation = np.tile(np.eye(2), (v, 1, 1))
    kids = np.nonzero(parent >= 0)[0]
    off = np.zeros((len(kids), 2, 2))
    for i in range(2):
        for j in range(2):
            off[:, i, j] = np.asarray(block[2 * kids + i, 2 * parent[kids] + j]).ravel()
    step = np.zeros((v, 2, 2))
    step[kids] = polar(-off)
    for u in order:
        if parent[u] >= 0:
            rotation[u] = step[u] @ rotation[parent[u]]
    rows = np.repeat(2 * np.arange(v)[:, None] + np.arange(2)[None, :], 2, axis=1).ravel()
    cols = np.tile(2 * aggregate[:, None] + np.arange(2)[None, :], (1, 2)).ravel()
    tentative = sp.csr_matrix((rotation.ravel(), (rows, cols)), shape=(2 * v, 2 * count))
    diagonal = sp.block_diag(list(np.linalg.inv(_vertex_blocks(block)))).tocsr()
    scaled = diagonal @ block
    x = np.random.default_rng(0).random(2 * v)
    for _ in range(10):
        x = scaled @ x
        largest = np.linalg.norm(x)
        x /= largest
    return tentative - (4 / (3 * largest)) * (scaled @ tentative)


def _depth(parent):
    depth = np.zeros(len(parent), int)
    for u in range(len(parent)):
        w = u
        while parent[w] >= 0:
            depth[u] += 1
            w = parent[w]
    return depth


def _vertex_blocks(block):
    c = block.tocoo()
    same = c.row // 2 == c.col // 2
    blocks = np.zeros((block.shape[0] // 2, 2, 2))
    np.add.at(blocks, (c.row[same] // 2, c.row[same] % 2, c.col[same] % 2), c.data[same])
    return blocks


def main():
    problem = Problem(sys.argv[1])
    middle = problem.slabs // 2
    print(f"slab Gauss-Seidel alone: {problem.iterations(problem.gauss_seidel)} iterations")
    for spec in sys.argv[2:]:
        parts = [bases_of(problem, middle, part) for part in spec.split("+")]
        bases = [sp.hstack([sp.csr_matrix(part[s]) for part in parts]) for s in range(problem.slabs)]
        size = bases[0].shape[1]
        print(f"{spec}: {size} coarse unknowns per slab, {problem.two_level(bases)} iterations")


def bases_of(problem, middle, spec):
    """One basis per slab for `spec` (see the module docs)."""
    kind, _, numbers = spec.partition(":")
    numbers = [int(x) for x in numbers.split(",")]
    if kind == "eig":
        return [lowest_eigenvectors(problem.blocks[middle], numbers[0])] * problem.slabs
    if kind == "random":
        return [randomized(problem, middle, *numbers)] * problem.slabs
    if kind == "aggregate":
        aggregate, parent, count = aggregates(vertex_graph(problem.blocks[0]), numbers[0])
        return [aggregation_basis(b.tocsr(), aggregate, parent, count) for b in problem.blocks]
    raise SystemExit(f"unknown basis {spec}")


if __name__ == "__main__":
    main()
