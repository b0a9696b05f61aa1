"""Cheaper cycles than meshflow's V-cycle, on a written system: iterations and slab solves.

  V(1,1)        meshflow's (src/flow/solve/multigrid.rs, time_multigrid.py): forward odd-even
                sweep, coarse cycle on the residual, backward sweep; CG.
  V(0,1)        the coarse cycle on r itself, then one forward sweep on the new residual: half
                the slab solves and residual products per cycle, but not symmetric, so flexible
                CG (time_multigrid.pcg's `flexible`).
  GS            slab Gauss-Seidel alone (a forward and a backward sweep); CG.
  GS+coarsest   slab Gauss-Seidel with one exact coarse solve between its sweeps, on the single
                slab that merges all of them (pairs prolongations chained, Galerkin operator); CG.

    cargo run --release --example space_time_system -- 48 36 40 0.01 0.01 /tmp/system
    python3 examples/scipy/cycle_variants.py /tmp/system [...]

(docs/scaling.md, "Cheaper cycles").
"""

import sys

import scipy.sparse.linalg as spla

from time_multigrid import Level, hierarchy, load, pairs_prolongation, pcg


class Counted:
    """A hierarchy's levels whose sweeps count the slab solves."""

    def __init__(self, levels, prolongations):
        self.levels, self.prolongations, self.solves = levels, prolongations, 0

    def sweep(self, l, r, first, second):
        self.solves += self.levels[l].slabs
        return self.levels[l].sweep(r, first, second)

    def v11(self, r, l=0):
        a, z = self.levels[l].a, self.sweep(l, r, 0, 1)
        if l + 1 == len(self.levels):
            return z
        p = self.prolongations[l]
        z = z + p @ self.v11(p.T @ (r - a @ z), l + 1)
        return z + self.sweep(l, r - a @ z, 1, 0)

    def v01(self, r, l=0):
        if l + 1 == len(self.levels):
            return self.sweep(l, r, 0, 1)
        p = self.prolongations[l]
        z = p @ self.v01(p.T @ r, l + 1)
        return z + self.sweep(l, r - self.levels[l].a @ z, 0, 1)


def coarsest_correction(fine):
    """`r -> P B⁻¹ Pᵀ r` onto the one slab that merges all of `fine`'s slabs (Galerkin
    `B = Pᵀ A P`)."""
    chained, level = None, fine
    while level.slabs > 1:
        p = pairs_prolongation(level)
        chained = p if chained is None else chained @ p
        level = Level((p.T @ level.a @ p).tocsr(), fine.n)
    factor = spla.splu((chained.T @ fine.a @ chained).tocsc())
    return lambda r: chained @ factor.solve(chained.T @ r)


def main():
    for directory in sys.argv[1:]:
        a, b, n = load(directory)
        counted = Counted(*hierarchy(a, n, "pairs"))
        fine = counted.levels[0]
        coarse = coarsest_correction(fine)

        def gauss_seidel(r, correct=False):
            z = counted.sweep(0, r, 0, 1)
            if correct:
                z = z + coarse(r - a @ z)
            return z + counted.sweep(0, r - a @ z, 1, 0)

        results = []
        for name, preconditioner, flexible in [
            ("V(1,1)", counted.v11, False),
            ("V(0,1) flexible", counted.v01, True),
            ("GS", gauss_seidel, False),
            ("GS+coarsest", lambda r: gauss_seidel(r, True), False),
        ]:
            counted.solves = 0
            iterations = pcg(lambda v: a @ v, b, preconditioner, flexible=flexible)[1]
            results.append(f"{name} {iterations} ({counted.solves} slab solves)")
        print(f"{directory}: " + ", ".join(results), flush=True)


if __name__ == "__main__":
    main()
