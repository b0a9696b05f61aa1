"""Slab Gauss-Seidel PCG against CG on the odd slabs' Schur complement, on a written system.

meshflow's slab Gauss-Seidel (src/flow/solve/precondition.rs) sweeps the slabs in odd-even
order: P = (D + L) D^-1 (D + U) with the even slabs first. Its preconditioned operator has the
eigenvalue 1 on the even slabs and the spectrum of D_o^-1 S on the odd ones, where
S = D_o - B^T D_e^-1 B is the odd slabs' Schur complement; so CG on S, preconditioned by the odd
slab blocks D_o, needs the same iterations at 19 slab solves per iteration (even and odd)
instead of 29 (even, odd, even again). With single-precision factors S is only approximate
(D_e^-1 rounded), so the reduced solve is refined against the double-precision residual of the
whole system (outer iterations, each an inner CG to INNER relative residual).

    cargo run --release --example space_time_system -- 128 95 20 1 1 /tmp/system
    python3 examples/scipy/odd_slab_schur.py /tmp/system [INNER ...]

prints, for f32 factors (SuperLU), the iterations and slab solves of both to 1e-8
(docs/scaling.md, "The odd slabs' Schur complement").
"""

import sys

import numpy as np
import scipy.sparse.linalg as spla

from time_multigrid import load, pcg

TOLERANCE = 1e-8


class Slabs:
    """Slab blocks of A (n unknowns each) with f32 factors, the links between them, and a count
    of slab solves."""

    def __init__(self, a, n):
        self.a, self.n, self.count = a, n, a.shape[0] // n
        blocks = [a[self.at(s), self.at(s)].tocsc() for s in range(self.count)]
        self.factors = [spla.splu(b.astype(np.float32), permc_spec="MMD_AT_PLUS_A") for b in blocks]
        self.solves = 0

    def at(self, s):
        return slice(s * self.n, (s + 1) * self.n)

    def of(self, parity):
        return [s for s in range(self.count) if s % 2 == parity]

    def solve(self, s, r):
        self.solves += 1
        return self.factors[s].solve(r.astype(np.float32)).astype(np.float64)

    def links(self, z, s):
        """Sum of A[s, t] z_t over the neighbouring slabs t."""
        out = np.zeros(self.n)
        for t in (s - 1, s + 1):
            if 0 <= t < self.count:
                out += self.a[self.at(s), self.at(t)] @ z[self.at(t)]
        return out


def gauss_seidel(slabs, r):
    """meshflow's odd-even symmetric sweep: even, odd, even again."""
    z = np.zeros_like(r)
    for s in slabs.of(0):
        z[slabs.at(s)] = slabs.solve(s, r[slabs.at(s)])
    for s in slabs.of(1):
        z[slabs.at(s)] = slabs.solve(s, r[slabs.at(s)] - slabs.links(z, s))
    for s in slabs.of(0):
        z[slabs.at(s)] -= slabs.solve(s, slabs.links(z, s))
    return z


def reduced_solve(slabs, r, inner):
    """A^-1 r through CG on the odd slabs' Schur complement (to `inner`), with back-substitution
    on the even slabs; returns the solution and the inner iterations."""
    odd, even = slabs.of(1), slabs.of(0)
    whole = np.zeros_like(r)

    def spread(x_odd):
        v = whole.copy()
        for k, s in enumerate(odd):
            v[slabs.at(s)] = x_odd[k * slabs.n:(k + 1) * slabs.n]
        return v

    def gather(v):
        return np.concatenate([v[slabs.at(s)] for s in odd])

    def even_solved(v):
        out = whole.copy()
        for s in even:
            out[slabs.at(s)] = slabs.solve(s, v[slabs.at(s)])
        return out

    def schur(p_odd):
        p = spread(p_odd)
        coupled = even_solved(np.concatenate([slabs.links(p, s) if s % 2 == 0 else np.zeros(slabs.n)
                                              for s in range(slabs.count)]))
        return gather(np.concatenate([slabs.a[slabs.at(s), slabs.at(s)] @ p[slabs.at(s)]
                                      - slabs.links(coupled, s) if s % 2 else np.zeros(slabs.n)
                                      for s in range(slabs.count)]))

    def odd_blocks(r_odd):
        return np.concatenate([slabs.solve(s, r_odd[k * slabs.n:(k + 1) * slabs.n])
                               for k, s in enumerate(odd)])

    y = even_solved(r)
    rhs = gather(r) - gather(np.concatenate([slabs.links(y, s) if s % 2 else np.zeros(slabs.n)
                                             for s in range(slabs.count)]))
    x_odd, iterations = pcg(schur, rhs, odd_blocks, inner)
    x = spread(x_odd)
    for s in even:
        x[slabs.at(s)] = slabs.solve(s, r[slabs.at(s)] - slabs.links(x, s))
    return x, iterations


def main():
    directory, inners = sys.argv[1], [float(t) for t in sys.argv[2:]] or [1e-4, 1e-3]
    a, b, n = load(directory)
    slabs = Slabs(a, n)
    x, iterations = pcg(lambda v: a @ v, b, lambda r: gauss_seidel(slabs, r), TOLERANCE)
    print(f"{directory}: slab Gauss-Seidel PCG {iterations} iterations, {slabs.solves} slab solves")
    reference = x
    for inner in inners:
        slabs.solves, x, total, outer = 0, np.zeros_like(b), 0, 0
        while (residual := np.linalg.norm(b - a @ x) / np.linalg.norm(b)) > TOLERANCE and outer < 30:
            correction, iterations = reduced_solve(slabs, b - a @ x, max(inner, 0.5 * TOLERANCE / residual))
            x, total, outer = x + correction, total + iterations, outer + 1
        difference = np.linalg.norm(x - reference) / np.linalg.norm(reference)
        print(f"  Schur complement CG, inner {inner:.0e}: {outer} refinements, {total} iterations, "
              f"{slabs.solves} slab solves, residual {residual:.1e}, differs by {difference:.1e}")


if __name__ == "__main__":
    main()
